"""A README's generated sections: the text between a start and an end marker, read and replaced
as a whole (`swingbench run` and `report --update-readme`: the verdicts between `README_START` and
`README_END`; `report --at-scale`: the verdict runs apart from the bench between `AT_SCALE_START`
and `AT_SCALE_END`; `report --step-claim`: pinnsim's step claim between `STEP_CLAIM_START` and
`STEP_CLAIM_END`; `swingbench compare --update-readme`: the comparison between its own markers).

This module imports only the standard library until it writes: the CLI imports it to build its
parser."""

from __future__ import annotations

from pathlib import Path

from harness.usage import UsageError

__all__ = ["AT_SCALE_END", "AT_SCALE_START", "README_END", "README_START", "STEP_CLAIM_END", "STEP_CLAIM_START", "around",
           "replace_section"]

README_START, README_END = "<!-- swingbench:tables:start -->", "<!-- swingbench:tables:end -->"
AT_SCALE_START, AT_SCALE_END = "<!-- swingbench:at-scale:start -->", "<!-- swingbench:at-scale:end -->"
STEP_CLAIM_START, STEP_CLAIM_END = "<!-- swingbench:step-claim:start -->", "<!-- swingbench:step-claim:end -->"


def around(path: Path, start: str, end: str, command: str, flag: str = "--update-readme") -> tuple[str, str]:
    """The text of `path` before `start` and after `end`; UsageError, one line naming `command`
    and its `flag`, when it cannot be read or lacks either marker (checked before a run measures,
    and again when it writes)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"swingbench {command}: {flag}: cannot read {path}: {exc}") from None
    if start not in text or end not in text:
        raise UsageError(f"swingbench {command}: {flag}: {path} has no {start} ... {end} section to update")
    head, rest = text.split(start, 1)
    return head, rest.split(end, 1)[1]


def replace_section(path: Path, start: str, end: str, block: str, command: str,
                    flag: str = "--update-readme") -> None:
    """Replace the text between the markers `start` and `end` of `path` with `block`, in one
    atomic write (`solvers.atomic.atomic_write`)."""
    from solvers.atomic import atomic_write

    head, tail = around(path, start, end, command, flag)
    atomic_write(path, head + start + block + end + tail)
