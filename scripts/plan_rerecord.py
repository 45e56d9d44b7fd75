"""Record tests/data/plan_before.json again when named configs join the registry: the plans of
tests/test_plan.py's runs, as that test computes them, with every entry the file held kept as it was
and in its order (asserted: an old entry that the plan no longer makes, or a new entry of any
other config, stops the script), the new configs' units inserted where the plan puts them.

    python scripts/plan_rerecord.py fault-split [...]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

FILE = Path(__file__).resolve().parent.parent / "tests" / "data" / "plan_before.json"


def planned(run: str) -> list[list]:
    """The works of `run` as tests/test_plan.py lists them."""
    sys.path.insert(0, str(FILE.parent.parent))
    from test_plan import planned as test_planned

    return test_planned(run)[1]


def merged(old: list[list], new: list[list], configs: set[str]) -> list[list]:
    """`old` with the entries of `new` that `old` lacks inserted in `new`'s order; asserts that
    those are of `configs` and that every entry of `old` but its "no rows" ones is in `new`, in order."""
    out, i = [], 0
    for entry in new:
        while i < len(old) and old[i][-1] == "no rows":
            out.append(old[i])
            i += 1
        if i < len(old) and old[i] == entry:
            out.append(entry)
            i += 1
            continue
        assert entry[2] in configs, f"a new entry of another config: {entry}"
        out.append(entry)
    rest = old[i:]
    assert all(entry[-1] == "no rows" for entry in rest), f"old entries the plan no longer makes: {rest[:3]}"
    return out + rest


def main(configs: list[str]) -> None:
    before = json.loads(FILE.read_text())
    after = {run: merged(entries, planned(run), set(configs)) for run, entries in before.items()}
    for run in before:
        print(f"{run}: {len(before[run])} entries, {len(after[run]) - len(before[run])} added")
    FILE.write_text(json.dumps(after, indent=1) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
