"""The run's provenance (`harness.provenance`): the commit, dirty only for what the run did not write."""

from __future__ import annotations


def test_git_commit_is_dirty_only_for_changes_the_run_did_not_write(tmp_path):
    import subprocess

    from harness.provenance import git_commit

    def git(*args):
        subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=tmp_path, check=True,
                       capture_output=True)

    (tmp_path / "results").mkdir()
    for name in ("code.py", "README.md", "results/tables.md"):
        (tmp_path / name).write_text("one\n")
    git("init", "-q")
    git("add", ".")
    git("commit", "-q", "-m", "one")
    outputs = [tmp_path / "results", tmp_path / "README.md"]
    assert not git_commit(tmp_path, outputs).endswith("+dirty")
    (tmp_path / "results" / "tables.md").write_text("two\n")
    (tmp_path / "README.md").write_text("two\n")
    assert not git_commit(tmp_path, outputs).endswith("+dirty")
    assert git_commit(tmp_path).endswith("+dirty")
    (tmp_path / "code.py").write_text("two\n")
    assert git_commit(tmp_path, outputs).endswith("+dirty")
    assert git_commit(tmp_path / "results", outputs).endswith("+dirty")  # from a subfolder too
    assert git_commit(tmp_path.parent / "no-such-checkout") == "unknown"
