"""The one way a command refuses bad input before it measures anything.

Only the standard library: the CLI's parser imports it.
"""

from __future__ import annotations

__all__ = ["EXIT_FAILED", "EXIT_USAGE", "UsageError"]

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
