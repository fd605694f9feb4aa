"""The committed replay vectors of a C build are what its Python twin writes today.

ctest replays them through the C build; stale vectors would prove nothing about the Python
build they stand for. Used by the RC-400 and DP-200 firmware tests.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

__all__ = ["assert_vectors_fresh"]


def assert_vectors_fresh(script: Path, committed: Path, scratch: Path, *, root: Path,
                         files: int) -> None:
    """Run the vectors ``script`` into ``scratch`` and require the same ``files`` files, line
    for line, as ``committed``."""
    subprocess.run([sys.executable, str(script), str(scratch)], check=True, cwd=root,
                   capture_output=True)
    written = sorted(p.name for p in scratch.iterdir())
    assert written == sorted(p.name for p in committed.iterdir()) and len(written) == files
    for name in written:
        assert (scratch / name).read_text() == (committed / name).read_text(), \
            f"{name} is stale: rerun {script.relative_to(root)} {committed.relative_to(root)}"
