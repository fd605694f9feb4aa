"""Atomic file writes: a reader (or a crash) never sees half a file.

Every ``record.json`` agrihil writes goes through :func:`write_json_atomic`: the text is
written to a temporary file in the same directory, flushed to disk, then renamed over the
target with :func:`os.replace` (atomic on POSIX). A process killed at any moment leaves
either the old file or the new one, never a truncated one.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (temporary file + :func:`os.replace`).

    Parameters
    ----------
    path : str or Path
        The file to (re)write; its directory must exist.
    text : str
        The new content (UTF-8).

    Returns
    -------
    Path
        ``path``.
    """
    target = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp",
                                   dir=target.parent)
    except OSError as exc:
        raise named_os_error(exc, target) from exc
    try:
        # mkstemp makes the file 0600; a record is as readable as any file the user writes
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except OSError as exc:   # "No space left on device" names the file it could not write
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise named_os_error(exc, target) from exc
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return target


def named_os_error(exc: OSError, path: str | Path) -> OSError:
    """``exc`` naming ``path`` when it names no file.

    A failed ``write`` or ``fsync`` names none, and "No space left on device" alone does not
    say which disk is full.

    Parameters
    ----------
    exc : OSError
        The error as raised.
    path : str or Path
        The file (or directory) being written.

    Returns
    -------
    OSError
        ``exc`` itself when it names a file, else a copy of it naming ``path``.
    """
    if exc.filename is not None:
        return exc
    named = type(exc)(exc.errno, exc.strerror or str(exc), str(path))
    named.__cause__ = exc
    return named


def write_json_atomic(path: str | Path, data: Any) -> Path:
    """Write ``data`` as indented JSON to ``path`` atomically (see :func:`write_text_atomic`).

    Parameters
    ----------
    path : str or Path
        The file to (re)write.
    data : Any
        JSON-serialisable data; anything else is written with ``str``.

    Returns
    -------
    Path
        ``path``.
    """
    return write_text_atomic(path, json.dumps(data, indent=2, default=str))
