"""Re-record tests/data/plan_before.json after a new adapter (or a new config of one) joined the
registry: the planner's units of every recorded run, checked to be the recorded ones with only the
new adapter's (config's) added.

    python tests/record_plan_before.py pinnsim
    python tests/record_plan_before.py pinnsim faults

Every other entry must be unchanged and in its order (else the script stops and writes nothing);
the new entries are inserted where the planner puts them, the recorded "no rows" entries kept
where they were.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).parent)]  # this checkout first

from test_plan import planned

FILE = Path(__file__).parent / "data" / "plan_before.json"


def merged(old: list[list], new: list[list], adapter: str, config: str | None = None) -> list[list]:
    """`old` with the entries of `adapter` (of its `config` alone, when given) in `new` inserted; a
    ValueError unless the rest of `new` is `old` without its "no rows" entries, in order."""
    def added(entry: list) -> bool:
        return entry[1] == adapter and config in (None, entry[2])

    what = adapter if config is None else f"{adapter} config {config}"
    if [e for e in new if not added(e)] != [e for e in old if e[-1] != "no rows"]:
        raise ValueError(f"the planner changed entries other than {what}'s")
    if any(added(e) for e in old):
        raise ValueError(f"{what} is recorded already")
    out, i = [], 0
    for entry in new:
        if not added(entry):
            while old[i][-1] == "no rows":
                out.append(old[i])
                i += 1
            assert old[i] == entry
            out.append(old[i])
            i += 1
        else:
            out.append(entry)
    return out + old[i:]


def main(adapter: str, config: str | None = None) -> int:
    before = json.loads(FILE.read_text())
    after = {}
    for run in before:
        after[run] = merged(before[run], planned(run)[1], adapter, config)
        added = len(after[run]) - len(before[run])
        print(f"{run}: {len(before[run])} entries kept, {added} of {adapter} {config or ''} added")
    FILE.write_text(json.dumps(after, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(*sys.argv[1:3]))
