"""The committed replay vectors of a C build are what its Python twin writes today.

ctest replays them through the C build; stale vectors would prove nothing about the Python
build they stand for. Used by the RC-400 and DP-200 firmware tests (whole files a script
writes) and the ISOBUS ones (one vector file recorded in process, named at its first stale
line).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

__all__ = ["assert_vector_file_fresh", "assert_vectors_fresh"]


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


def assert_vector_file_fresh(path: Path, fresh: list[str], *, twin: str, rewrite: str) -> None:
    """Require the committed vector file ``path`` to be ``fresh`` (the lines its Python
    ``twin`` records today), naming the first line that differs and how to ``rewrite`` it."""
    committed = path.read_text().splitlines()
    first = next((i for i, (a, b) in enumerate(zip(committed, fresh, strict=False)) if a != b),
                 min(len(committed), len(fresh)))
    assert committed == fresh, (
        f"{path.name} is stale at line {first + 1}: committed {committed[first:first + 1]}, "
        f"{twin} now {fresh[first:first + 1]}; rewrite it with {rewrite} and run ctest")
