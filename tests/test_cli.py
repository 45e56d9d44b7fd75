"""The command line: its parser, its help, and what `run` and `report` do end to end on cheap solvers."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_building_the_parser_imports_no_numerical_library():
    """`swingbench --help` and every command's parser need the standard library, the CLI's modules and
    the solver registry's names only: none of numpy, pandas, scipy or matplotlib (a fresh interpreter)."""
    code = ("import sys\nfrom harness.cli import _parser\n_parser()\n"
            "print(sorted({'numpy', 'pandas', 'scipy', 'matplotlib'} & set(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
