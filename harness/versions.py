"""Installed library versions: recorded with a run and in the model cache's key. Standard library only."""

from __future__ import annotations

import importlib.metadata

__all__ = ["library_versions"]


def library_versions(libraries: tuple[str, ...]) -> dict[str, str]:
    """Installed versions of `libraries` ("not installed" for a missing one)."""
    versions = {}
    for lib in libraries:
        try:
            versions[lib] = importlib.metadata.version(lib)
        except importlib.metadata.PackageNotFoundError:
            versions[lib] = "not installed"
    return versions
