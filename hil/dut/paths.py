"""Where a profile's relative paths start: the project root.

Its own module so that the profile loader (which resolves ``wiring.database``) and the build
(which resolves ``build.sources``) both read it without importing each other.
"""

from __future__ import annotations

from pathlib import Path

#: the agrihil project root (``{root}`` in a profile's commands)
PROJECT_ROOT = Path(__file__).resolve().parents[2]
