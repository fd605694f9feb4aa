"""Something a test session builds once for all its pytest-xdist workers.

A ``scope="session"`` fixture is per process: with ``-n 2`` (``scripts/test.sh``) each worker
that runs a test needing it builds it again, and an expensive one (a qualification, ~5-15 s)
costs twice. :func:`built_once` gives a directory every worker of the session sees, taken under
a lock file: the first worker to need it builds it, the others wait for it and reuse it.

(``xdist_group`` marks, the other way of keeping such tests on one worker, do nothing with
pytest 9.2 and pytest-xdist 3.8: xdist renames ``item._nodeid``, which pytest no longer reads.)
"""

from __future__ import annotations

import fcntl
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest


def session_root(factory: pytest.TempPathFactory) -> Path:
    """The session's base directory, shared by its xdist workers and by no other session.

    Under xdist each worker's base directory is one of the session's (``.../popen-gwN``), so
    their parent is the session's; without xdist it is the base directory itself.
    """
    base = factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


@contextmanager
def built_once(factory: pytest.TempPathFactory, name: str) -> Iterator[tuple[Path, bool]]:
    """``(directory, built)``: the session's directory ``name``, and whether it is already
    built. When it is not, the caller builds it inside the ``with`` block, holding the lock
    (other workers wait); it counts as built only if the block ends without an exception, so
    a failed build is tried again, and fails again, where it is needed next."""
    root = session_root(factory) / "built-once"
    root.mkdir(exist_ok=True)
    target, done = root / name, root / f"{name}.done"
    with (root / f"{name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)              # released when the file is closed
        if done.exists():
            yield target, True
            return
        shutil.rmtree(target, ignore_errors=True)     # what a failed build left
        target.mkdir()
        yield target, False
        done.touch()
