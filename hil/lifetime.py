"""Child processes die with agrihil: no DUT (nor anything it started) outlives the rig.

Two mechanisms, because one is not enough:

* :func:`die_with_parent` is a ``preexec_fn`` for :class:`subprocess.Popen` that asks the
  kernel (``prctl(PR_SET_PDEATHSIG, SIGKILL)``) to kill the child the moment the process that
  started it dies, even by SIGKILL. It covers the child itself, not what the child starts.
* The :class:`Guardian` is one small process per agrihil process (started on first use, in a
  session of its own so a Ctrl-C or a group kill does not reach it). agrihil tells it which
  processes to watch; it follows each one's process tree through ``/proc`` (so a helper that
  escapes into its own session is still known) and kills every process of the tree when
  agrihil asks (:meth:`Guardian.kill_tree`, on a normal stop) or when agrihil's end of its
  pipe closes, which is how the guardian learns that agrihil died, however it died.

The guardian is ``python -m hil.lifetime``; it reads ``watch PID``, ``scan PID``,
``kill PID`` and ``release PID`` lines on stdin and answers ``scan`` and ``kill`` with
``done N`` (the processes it knows in the tree / it killed).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import selectors
import signal
import subprocess
import sys
import threading
from collections.abc import Callable
from pathlib import Path

PR_SET_PDEATHSIG = 1
#: how often the guardian rescans the watched trees (s)
SCAN_PERIOD_S = 0.2

_libc = ctypes.CDLL(None, use_errno=True)    # the C library the interpreter is linked with
_prctl = _libc.prctl
_prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong,
                   ctypes.c_ulong]


def die_with_parent(sig: int = signal.SIGKILL) -> Callable[[], None]:
    """A ``preexec_fn`` that makes the child receive ``sig`` when its parent dies.

    Parameters
    ----------
    sig : int
        The signal the kernel sends the child on the parent's death (default SIGKILL).

    Returns
    -------
    callable
        To pass as ``preexec_fn`` (it also covers a parent that died between ``fork`` and
        the ``prctl``: the child then exits at once).

    Notes
    -----
    Linux sends the signal when the *thread* that started the child ends: start children from
    a thread that lives as long as they should (the main thread, in agrihil).
    """
    parent = os.getpid()

    def preexec() -> None:
        _prctl(PR_SET_PDEATHSIG, sig, 0, 0, 0)
        if os.getppid() != parent:       # the parent died before the prctl
            os._exit(1)
    return preexec


# --- /proc ----------------------------------------------------------------------------------
def _stat(pid: int) -> tuple[int, int] | None:
    """(ppid, start time in clock ticks) of ``pid``, or None when it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2:].split()
    return int(fields[1]), int(fields[19])


def process_table() -> dict[int, tuple[int, int]]:
    """Every process: pid -> (ppid, start time)."""
    table = {}
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            stat = _stat(int(entry.name))
            if stat is not None:
                table[int(entry.name)] = stat
    return table


def descendants(root: int, table: dict[int, tuple[int, int]] | None = None) -> dict[int, int]:
    """The processes below ``root`` (not ``root`` itself): pid -> start time."""
    table = process_table() if table is None else table
    children: dict[int, list[int]] = {}
    for pid, (ppid, _) in table.items():
        children.setdefault(ppid, []).append(pid)
    out: dict[int, int] = {}
    todo = list(children.get(root, ()))
    while todo:
        pid = todo.pop()
        if pid not in out:
            out[pid] = table[pid][1]
            todo += children.get(pid, ())
    return out


def _kill_known(known: dict[int, int]) -> int:
    """SIGKILL each pid whose start time still matches (never a reused pid); how many."""
    killed = 0
    for pid, started in known.items():
        stat = _stat(pid)
        if stat is not None and stat[1] == started:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal.SIGKILL)
                killed += 1
    return killed


# --- the guardian process ---------------------------------------------------------------------
def _guard() -> int:
    """The guardian's loop (``python -m hil.lifetime``)."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)
    trees: dict[int, dict[int, int]] = {}      # root pid -> every pid seen below it (+ root)
    stdin = sys.stdin.fileno()
    sel = selectors.DefaultSelector()
    sel.register(stdin, selectors.EVENT_READ)
    pending = b""

    def scan() -> None:
        if not trees:
            return
        table = process_table()
        for root, known in trees.items():
            known.update(descendants(root, table))
            for pid in [p for p in known if p not in table]:   # gone: forget it
                del known[pid]

    def handle(line: str) -> None:
        command, _, arg = line.strip().partition(" ")
        pid = int(arg) if arg.isdigit() else -1
        if command == "watch" and pid > 0:
            stat = _stat(pid)
            trees[pid] = {pid: stat[1]} if stat else {}
            scan()
        elif command == "kill":
            scan()
            known = trees.pop(pid, {})
            known.pop(pid, None)               # the leader is the caller's to stop
            os.write(sys.stdout.fileno(), f"done {_kill_known(known)}\n".encode())
        elif command == "scan":                # now, while the tree is whole; then ack
            scan()
            os.write(sys.stdout.fileno(), f"done {len(trees.get(pid, {}))}\n".encode())
        elif command == "release":
            trees.pop(pid, None)

    while True:
        if not sel.select(SCAN_PERIOD_S):
            scan()
            continue
        data = os.read(stdin, 4096)
        if not data:                           # agrihil is gone: nothing it started stays
            scan()
            for root, known in trees.items():
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(root, signal.SIGKILL)
                _kill_known(known)
            return 0
        pending += data
        while b"\n" in pending:
            line, pending = pending.split(b"\n", 1)
            handle(line.decode(errors="replace"))


class Guardian:
    """agrihil's end of the guardian process (one per agrihil process: :func:`guardian`)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.proc: subprocess.Popen[str] | None = None

    def _ensure(self) -> subprocess.Popen[str]:
        if self.proc is None or self.proc.poll() is not None:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "hil.lifetime"], stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, text=True, start_new_session=True,
                env={**os.environ, "PYTHONUNBUFFERED": "1"})
        return self.proc

    def _send(self, line: str, *, answer: bool = False) -> str:
        with self._lock:
            try:
                proc = self._ensure()
                assert proc.stdin is not None and proc.stdout is not None
                proc.stdin.write(line + "\n")
                proc.stdin.flush()
                return proc.stdout.readline().strip() if answer else ""
            except (OSError, ValueError):
                return ""                      # a dead guardian must not break a run

    def watch(self, pid: int) -> None:
        """Follow ``pid``'s process tree from now on (and kill it if agrihil dies)."""
        self._send(f"watch {pid}")

    def kill_tree(self, pid: int) -> int:
        """SIGKILL every process ever seen below ``pid`` that still lives (``pid`` itself is
        the caller's to stop); forget ``pid``. Returns how many were killed."""
        reply = self._send(f"kill {pid}", answer=True)
        return int(reply.split()[1]) if reply.startswith("done ") else 0

    def scan(self, pid: int) -> int:
        """Note ``pid``'s tree as it is now (before stopping it: once the leader is gone, its
        children belong to nobody); returns how many processes are known in it."""
        reply = self._send(f"scan {pid}", answer=True)
        return int(reply.split()[1]) if reply.startswith("done ") else 0

    def release(self, pid: int) -> None:
        """Stop following ``pid`` (it and its tree ended by themselves)."""
        self._send(f"release {pid}")


_GUARDIAN = Guardian()


def guardian() -> Guardian:
    """The guardian of this process (started on first use)."""
    return _GUARDIAN


if __name__ == "__main__":
    sys.exit(_guard())
