"""mkdocs hook (mkdocs.yml `hooks:`): files made outside docs/ that the site serves, added to the
build's files instead of copied into docs/:

- every PNG that `swingbench report` wrote under results/, at `figures/<its path under results/>`:
  a narrative page links `figures/scaling/scaling_cost.png` for results/scaling/scaling_cost.png
  and always shows the committed figure (results/runs/, scratch runs that git ignores, left out);
- the asv benchmark history that `make asv-publish` rendered into .asv/html, at `asv/`
  (`make docs` publishes it first).

A link to a file that is not there fails `mkdocs build --strict` like any broken link; a missing
asv history is a warning that says how to make it.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

log = logging.getLogger("mkdocs.hooks.extra_files")

# (folder under the repository, where the site serves it, which files, sub-folders left out)
SOURCES = (
    ("results", "figures", "*.png", ("runs",)),
    (".asv/html", "asv", "*", ()),
)


def on_files(files: Files, config: Any) -> Files:
    root = Path(config.config_file_path).parent
    for folder, prefix, pattern, skipped in SOURCES:
        source = root / folder
        if not source.is_dir():
            log.warning(f"{folder}/ is missing: the site's {prefix}/ needs it (`make asv-publish`)")
            continue
        for path in sorted(source.rglob(pattern)):
            relative = path.relative_to(source)
            if path.is_file() and relative.parts[0] not in skipped:
                files.append(File.generated(config, f"{prefix}/{relative.as_posix()}", abs_src_path=str(path)))
    return files
