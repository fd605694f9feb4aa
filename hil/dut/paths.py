"""Where a profile's relative paths start: the project root.

Its own module so that the profile loader (which resolves ``wiring.database`` and names the
code under test) and the build (which resolves ``build.sources``) both read it, and where the
build cache is, without importing each other.
"""

from __future__ import annotations

import os
from pathlib import Path

#: the agrihil project root (``{root}`` in a profile's commands)
PROJECT_ROOT = Path(__file__).resolve().parents[2]


def cache_root() -> Path:
    """The build cache's directory.

    ``$AGRIHIL_CACHE`` if set, else ``agrihil`` under ``$XDG_CACHE_HOME`` (default ``~/.cache``).
    """
    explicit = os.environ.get("AGRIHIL_CACHE")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "agrihil"


def build_entry(source_sha256: str) -> Path:
    """The build cache entry of a source set (its SHA-256; the key is its first 16 digits)."""
    return cache_root() / "builds" / f"build-{source_sha256[:16]}"
