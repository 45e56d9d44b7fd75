"""How a command ends other than by measuring: the one way it refuses bad input before it
measures anything (`UsageError`), and what counts as an interrupt (`raise_if_interrupted`).

Only the standard library: the CLI's parser imports it.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["EXIT_FAILED", "EXIT_USAGE", "UsageError", "check_known", "raise_if_interrupted"]

EXIT_USAGE = 2  # argparse's status for a bad command line: bad input of any kind, before measuring
EXIT_FAILED = 1  # the command ran, and some unit of work failed (or was lost): its rows say which


class UsageError(SystemExit):
    """Bad input found before anything is measured: an unknown name, an option value that is
    invalid on a selected case or on this machine, an unusable --out. `harness.cli.main` prints the
    message as one line on stderr; the process exits with `EXIT_USAGE`, without a traceback.

    A `SystemExit` whose code is the status and whose str is the message, so that it stops a
    command from anywhere below `main` and the interpreter does not print it a second time."""

    def __init__(self, message: str) -> None:
        super().__init__(EXIT_USAGE)
        self.message = message

    def __str__(self) -> str:
        return self.message


def check_known(command: str, what: str, given: Iterable[str] | None, known: Iterable[str]) -> None:
    """UsageError naming every name of `given` that is not in `known` and listing the known ones
    ("swingbench run: unknown solver(s) 'rk4'; known: ..."); nothing when all are known."""
    known = list(known)
    unknown = [name for name in given or [] if name not in known]
    if unknown:
        raise UsageError(f"swingbench {command}: unknown {what} {', '.join(map(repr, unknown))}; "
                         f"known: {', '.join(known)}")


def raise_if_interrupted(exc: BaseException) -> None:
    """Raise KeyboardInterrupt (from `exc`) when `exc` is a KeyboardInterrupt or was raised from one
    or while handling one (anywhere along its `__cause__` and `__context__` links); else return.
    For code that turns exceptions into results: compiled code turns a Ctrl-C during a call into
    another exception (numba's dispatcher raises `SystemError: CPUDispatcher(...) returned a result
    with an exception set` from the KeyboardInterrupt), which is an interrupt, not a result."""
    seen: set[int] = set()
    todo: list[BaseException | None] = [exc]
    while todo:
        link = todo.pop()
        if link is None or id(link) in seen:
            continue
        if isinstance(link, KeyboardInterrupt):
            raise KeyboardInterrupt from exc
        seen.add(id(link))
        todo += [link.__cause__, link.__context__]


def failure_status(exc: BaseException) -> str:
    """The status of work that raised `exc`: 'failed: <type>: <message>'. An interrupt is not a
    failure: when `exc` comes of a KeyboardInterrupt (a Ctrl-C inside numba, JAX or torch code), a
    KeyboardInterrupt is raised instead (`raise_if_interrupted`), so that the run stops as on a
    Ctrl-C anywhere else: the work unrecorded, measured by `--resume`."""
    raise_if_interrupted(exc)
    return f"failed: {type(exc).__name__}: {exc}"
