"""Re-record tests/data/plan_before.json after a new adapter joined the registry: the planner's
units of every recorded run, checked to be the recorded ones with only the new adapter's added.

    python tests/record_plan_before.py pinnsim

Every entry of another adapter must be unchanged and in its order (else the script stops and
writes nothing); the new adapter's entries are inserted where the planner puts them, the recorded
"no rows" entries kept where they were.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).parent)]  # this checkout first

from test_plan import planned

FILE = Path(__file__).parent / "data" / "plan_before.json"


def merged(old: list[list], new: list[list], adapter: str) -> list[list]:
    """`old` with the entries of `adapter` in `new` inserted; a ValueError unless the rest of `new`
    is `old` without its "no rows" entries, in order."""
    if [e for e in new if e[1] != adapter] != [e for e in old if e[-1] != "no rows"]:
        raise ValueError("the planner changed entries of other adapters")
    if any(e[1] == adapter for e in old):
        raise ValueError(f"{adapter} is recorded already")
    out, i = [], 0
    for entry in new:
        if entry[1] != adapter:
            while old[i][-1] == "no rows":
                out.append(old[i])
                i += 1
            assert old[i] == entry
            out.append(old[i])
            i += 1
        else:
            out.append(entry)
    return out + old[i:]


def main(adapter: str) -> int:
    before = json.loads(FILE.read_text())
    after = {}
    for run in before:
        after[run] = merged(before[run], planned(run)[1], adapter)
        added = len(after[run]) - len(before[run])
        print(f"{run}: {len(before[run])} entries kept, {added} of {adapter} added")
    FILE.write_text(json.dumps(after, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1]))
