"""`make asv-compare`: a regression gate between a base commit and HEAD, in the project's own .venv.

`make asv` runs asv with `--environment existing` (the .venv, which holds the project installed
editable), so asv cannot install another commit itself. This script checks each commit out into
its own git worktree under .asv/compare/trees/, runs asv there in the same .venv with that
worktree first on the import path (ASV_PYTHONPATH: asv drops PYTHONPATH), records the results
under the commit's hash in .asv/compare/results/ (scratch, never the kept history of
benchmarks/results/), then compares the two as `asv compare --split --factor F` does (only the
benchmarks that changed, as `asv continuous` shows them, unless --all). Each commit
is measured with its own benchmarks/; a benchmark whose code differs between them is "not
comparable" (asv's benchmark version), not a regression.

Exit status: 1 when a benchmark got slower (or larger) than the factor allows and asv's statistics
call the difference significant, or started failing; 0 otherwise.

    python scripts/asv_compare.py [--base REV] [--factor 1.1] [--all] [ASV RUN OPTIONS, e.g. --bench REGEX]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORK = ROOT / ".asv" / "compare"


def _git(*args: str, cwd: Path = ROOT) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True, text=True).stdout.strip()


def _tree(commit: str) -> Path:
    """A worktree of `commit` (reused: its numba cache and trained models stay warm)."""
    tree = WORK / "trees" / commit[:12]
    if not (tree / ".git").exists():
        _git("worktree", "prune")
        _git("worktree", "add", "--detach", "--force", str(tree), commit)
    return tree


def _config(tree: Path) -> Path:
    """The worktree's own asv.conf.json, its results in the shared scratch folder."""
    conf = json.loads((tree / "asv.conf.json").read_text())
    conf.update(repo=".", results_dir=str(WORK / "results"), html_dir=str(WORK / "html"),
                env_dir=str(WORK / "env"))
    path = tree / ".asv-compare.json"
    path.write_text(json.dumps(conf, indent=4) + "\n")
    return path


def _run(commit: str, python: Path, asv_args: list[str]) -> Path:
    tree = _tree(commit)
    config = _config(tree)
    env = {**os.environ, "ASV_PYTHONPATH": str(tree)}
    command = [str(python), "-m", "asv", "run", "--config", str(config), "--environment", f"existing:{python}",
               "--set-commit-hash", commit, "--show-stderr", *asv_args]
    print(f"[asv-compare] {commit[:12]} in {tree.relative_to(ROOT)}: {' '.join(command[3:])}", flush=True)
    # asv run exits 2 when a benchmark failed: the comparison reports that as a failure introduced or
    # one both commits share, so go on to it
    subprocess.run(command, cwd=tree, env=env, check=False)
    return config


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", default="main", help="the commit to compare HEAD against (default: main)")
    parser.add_argument("--factor", type=float, default=1.1, help="the ratio beyond which a change counts")
    parser.add_argument("--all", action="store_true",
                        help="every benchmark in the table, not only those that changed (as asv continuous)")
    # any other option (`--bench REGEX`, `-a repeat=3`, ...) goes to both `asv run`s
    args, asv_args = parser.parse_known_args()

    base, head = _git("rev-parse", "--verify", f"{args.base}^{{commit}}"), _git("rev-parse", "HEAD")
    if base == head:
        print(f"[asv-compare] HEAD is {args.base} ({head[:12]}): nothing to compare (BASE=HEAD~1?)")
        return 0
    if _git("status", "--porcelain", "--untracked-files=no"):
        print("[asv-compare] the working tree has uncommitted changes: HEAD is measured as committed")
    python = Path(sys.executable)
    _run(base, python, asv_args)
    config = _run(head, python, asv_args)

    from asv.commands.compare import Compare
    from asv.config import Config
    from asv.machine import Machine

    machine = Machine.get_unique_machine_name()
    print(f"\n[asv-compare] {args.base} ({base[:12]}) -> HEAD ({head[:12]}), factor {args.factor}, "
          f"machine {machine}:\n", flush=True)
    worsened, _ = Compare.print_table(Config.load(str(config)), base, head, factor=args.factor, split=True,
                                      only_changed=not args.all, machine=machine,
                                      commit_names={base: args.base, head: "HEAD"})
    if worsened:
        print(f"\n[asv-compare] REGRESSION: HEAD is slower than {args.base} beyond {args.factor}x (or fails)")
        return 1
    print(f"\n[asv-compare] no regression beyond {args.factor}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
