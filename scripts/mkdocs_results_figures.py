"""mkdocs hook (mkdocs.yml `hooks:`): the figures that `swingbench report` wrote under results/ are
part of the site, at `figures/<their path under results/>`.

mkdocs serves only files under docs_dir; this adds every PNG of results/ to the build's files
instead of copying them there, so a narrative page links `figures/scaling/scaling_cost.png` for
results/scaling/scaling_cost.png and always shows the committed figure. A link to a figure that is
not there fails `mkdocs build --strict` like any broken link. results/runs/ (scratch runs, ignored
by git) is left out.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

PREFIX = "figures"
SKIPPED = ("runs",)


def on_files(files: Files, config: Any) -> Files:
    results = Path(config.config_file_path).parent / "results"
    for png in sorted(results.rglob("*.png")):
        relative = png.relative_to(results)
        if relative.parts[0] in SKIPPED:
            continue
        files.append(File.generated(config, f"{PREFIX}/{relative.as_posix()}", abs_src_path=str(png)))
    return files
