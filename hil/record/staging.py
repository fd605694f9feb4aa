"""Stage, then promote: how every command that writes into ``--out`` writes.

A command's outputs (a record, its report, its run directories) are written into a hidden
staging directory inside ``--out`` and moved in only when the command ends, the record last and
atomically (:meth:`Staging.promote`). So

* a command that fails before it begins (a bad option, an unreachable scheduler, a full disk)
  leaves ``--out`` exactly as it found it (:meth:`Staging.discard`);
* once it has begun, ``--out``'s record says "not finished" until it has (the placeholder of
  :meth:`Staging.begin`), and the previous record is kept as ``<record>.previous.json``: a kill
  at any moment leaves a record that no gate passes and loses nothing already recorded;
* a write that fails for want of space (or the disk refusing it otherwise: quota, file size
  limit, read-only, I/O error; :data:`STORAGE_ERRNOS`) names the path it was writing, and the
  staging directory is removed; any other ``OSError`` (a connection reset, say) is left to the
  command, which promotes what it recorded.

SIGINT and SIGTERM are held (pending, never dropped) while the staging directory and the
placeholder are made and while outputs move in; they arrive as soon as the move is done.
"""

from __future__ import annotations

import contextlib
import errno
import glob
import os
import shutil
import signal
import threading
import uuid
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import Any

from hil.record.atomic import named_os_error, write_json_atomic

__all__ = ["STORAGE_ERRNOS", "Staging", "is_storage_error", "named_os_error", "signals_held"]

#: the errors of a disk refusing a write: full, over quota, beyond the file size limit
#: (``RLIMIT_FSIZE``), read-only, failing
STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EIO})


def is_storage_error(exc: BaseException) -> bool:
    """True for an ``OSError`` that says the disk refused a write (:data:`STORAGE_ERRNOS`)."""
    return isinstance(exc, OSError) and exc.errno in STORAGE_ERRNOS


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """SIGINT/SIGTERM wait inside the block, then arrive: held, never lost.

    The Python handlers are swapped for one that only notes the signal; on leaving the block
    the previous handlers are put back and each noted signal is handed to its handler (so
    ``hil``'s handler raises ``KeyboardInterrupt`` right after the block). Blocking with
    ``pthread_sigmask`` would not do: it holds signals for the calling thread only, and the
    kernel hands a process-directed signal to any other thread (a bus reader, a DUT watcher),
    whose C handler then has Python run the handler in the main thread all the same, in the
    middle of the block. Outside the main thread (where Python runs no handler) it does
    nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    noted: list[int] = []

    def note(signum: int, frame: FrameType | None) -> None:
        noted.append(signum)

    held = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.signal(sig, note) for sig in held}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for signum in noted:
            handler = previous[signal.Signals(signum)]
            if callable(handler):
                handler(signum, None)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)


class Staging:
    """The staging directory of one command writing into ``out``.

    Parameters
    ----------
    out : Path
        The output directory (it must exist).
    prefix : str
        The staging directory's name prefix (``.qualify-``, ``.campaign-``); followed by the
        process id, so a later command can tell a dead command's staging from a live one's.
    outputs : sequence of str, or None
        The files and directories the command writes besides the record, moved in first (a
        name may hold wildcards: ``as-applied-*.geojson``);
        None: whatever the command staged (``hil run``: the run's directory holds only the
        run's files, whose names depend on the DUT).
    record : str
        The record's file name, moved in last.

    Examples
    --------
    >>> import tempfile, json
    >>> out = Path(tempfile.mkdtemp())
    >>> staging = Staging(out, prefix=".demo-", outputs=("report.html",), record="r.json")
    >>> staging.begin({"status": "interrupted"})
    >>> _ = (staging.path / "r.json").write_text('{"status": "complete"}')
    >>> staging.promote()
    >>> json.loads((out / "r.json").read_text())["status"], staging.path.exists()
    ('complete', False)
    """

    def __init__(self, out: Path, *, prefix: str, outputs: Sequence[str] | None,
                 record: str) -> None:
        self.out = Path(out)
        self.prefix = prefix
        self.outputs = None if outputs is None else tuple(outputs)
        self.record = record
        self.run_id = uuid.uuid4().hex[:12]
        self.path = self.out / f"{prefix}{os.getpid()}-{self.run_id}"

    @property
    def previous(self) -> Path:
        """Where the record found in ``out`` is kept while (and after) this one is made."""
        return self.out / (Path(self.record).stem + ".previous" + Path(self.record).suffix)

    def clear_stale(self) -> None:
        """Remove staging directories of this kind whose process is gone (killed)."""
        for stale in self.out.glob(f"{self.prefix}*"):
            pid = stale.name.removeprefix(self.prefix).split("-", 1)[0]
            if pid.isdigit() and not Path(f"/proc/{pid}").exists():
                shutil.rmtree(stale, ignore_errors=True)

    def begin(self, placeholder: dict[str, Any] | None) -> None:
        """Make the staging directory, and with ``placeholder`` mark ``out`` as in progress.

        The record found in ``out`` is kept as :attr:`previous` and ``placeholder`` (a record
        saying "not finished") takes its place. Both or neither, signals held; the copy is
        made inside the staging directory and renamed, so a disk too full for it leaves no
        half-copied :attr:`previous`.
        """
        self.clear_stale()
        with signals_held():
            try:
                self.path.mkdir()
                if placeholder is not None:
                    if (self.out / self.record).exists():
                        kept = self.path / ".previous"
                        shutil.copy2(self.out / self.record, kept)
                        os.replace(kept, self.previous)
                    write_json_atomic(self.out / self.record, placeholder)
            except OSError as exc:
                shutil.rmtree(self.path, ignore_errors=True)
                raise named_os_error(exc, self.out) from exc

    def promote(self) -> None:
        """Move the staged outputs into ``out``, the record last, and remove the staging.

        Each old output goes aside only once its replacement is there to take its place; the
        record moves atomically. Signals are held until it is done.
        """
        with signals_held():
            trash = self.path / ".replaced"
            try:
                trash.mkdir(exist_ok=True)
                for name in self._staged_outputs():
                    new = self.path / name
                    if not new.exists():
                        continue
                    old = self.out / name
                    if old.exists() or old.is_symlink():
                        os.replace(old, trash / name)
                    os.replace(new, old)
                if (self.path / self.record).exists():
                    os.replace(self.path / self.record, self.out / self.record)
            except OSError as exc:
                raise named_os_error(exc, self.out) from exc
            finally:
                shutil.rmtree(self.path, ignore_errors=True)

    def _staged_outputs(self) -> tuple[str, ...]:
        if self.outputs is not None:
            # a name with a wildcard (``as-applied-*.geojson``) stands for what it matches
            return tuple(dict.fromkeys(
                found for name in self.outputs
                for found in ((name,) if not glob.has_magic(name) else
                              sorted(q.name for q in self.path.glob(name)))))
        return tuple(sorted(p.name for p in self.path.iterdir()
                            if p.name != self.record and not p.name.startswith(".")))

    def discard(self) -> None:
        """Remove the staging directory and what it holds (``out`` is left as it is)."""
        shutil.rmtree(self.path, ignore_errors=True)

    @contextlib.contextmanager
    def writing(self) -> Iterator[Path]:
        """A block that writes into the staging directory.

        A write the disk refused (:func:`is_storage_error`) removes the staging directory and
        is re-raised naming ``out`` when it names no file. Any other error goes on as it is.
        """
        try:
            yield self.path
        except OSError as exc:
            if not is_storage_error(exc):
                raise
            self.discard()
            raise named_os_error(exc, self.out) from exc
