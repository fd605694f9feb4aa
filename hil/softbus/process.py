"""The software bus in a child process (``python -m hil bus serve``), started and stopped from
this one.

The child dies with its parent, however the parent ends (SIGKILL included): on Linux it asks
the kernel for SIGTERM when its parent dies (``prctl(PR_SET_PDEATHSIG)``, set between fork
and exec), and on every system it stops when its stdin, a pipe from the parent, reaches EOF
(the kernel closes the parent's end when the parent dies).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from hil.softbus.control import CONTROL_TOKEN_ENV, control, new_token
from hil.softbus.settings import (
    BUSY_POLL_ENV,
    DEFAULT_CHANNEL,
    SoftwareBusError,
    check_loopback,
)

PR_SET_PDEATHSIG = 1


def die_with_parent() -> Callable[[], None] | None:
    """A ``preexec_fn`` that has the kernel send the child SIGTERM when this process dies.

    Linux only (None elsewhere, or when libc has no ``prctl``). Also None when called from a
    thread other than the main one: the kernel signals the child when the *thread* that forked
    it ends, so a worker thread's exit would kill a bus that should live on; the stdin pipe
    still ties the child to the process then.

    Returns
    -------
    callable or None
        The function to pass as ``preexec_fn``; it only calls a function looked up here.
    """
    if not sys.platform.startswith("linux"):
        return None
    if threading.current_thread() is not threading.main_thread():
        return None
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    parent = os.getpid()
    sigterm = int(signal.SIGTERM)

    def preexec() -> None:
        prctl(PR_SET_PDEATHSIG, sigterm, 0, 0, 0)
        if os.getppid() != parent:  # the parent died before the request took effect
            os.kill(os.getpid(), sigterm)

    return preexec


class SoftwareBusProcess:
    """The software bus in a child process (``python -m hil bus serve``).

    ``busy_poll_us`` goes to the child as ``AGRIHIL_SOFTBUS_BUSY_POLL_US`` (None: the child's
    default, :data:`DEFAULT_BUSY_POLL_US`, unless the variable is set in this process).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, bitrate: int | None = None,
                 log_path: str | Path | None = None, seed: int = 0,
                 busy_poll_us: float | None = None) -> None:
        check_loopback(host, False)
        self.host = host
        self.port = port
        self._args = [sys.executable, "-m", "hil", "bus", "serve", "--host", host,
                      "--port", str(port), "--seed", str(seed), "--exit-with-stdin"]
        if bitrate:
            self._args += ["--bitrate", str(bitrate)]
        if log_path:
            self._args += ["--log", str(log_path)]
        #: the child's control token (passed in its environment): :meth:`stats` uses it
        self.control_token = new_token()
        self._env = {**os.environ, "PYTHONUNBUFFERED": "1", CONTROL_TOKEN_ENV: self.control_token}
        if busy_poll_us is not None:
            self._env[BUSY_POLL_ENV] = str(max(0.0, busy_poll_us))
        self.proc: subprocess.Popen[str] | None = None
        self._stderr_tail: deque[str] = deque(maxlen=40)
        self._stderr_thread: threading.Thread | None = None

    def start(self, timeout: float = 10.0) -> SoftwareBusProcess:
        self.proc = subprocess.Popen(self._args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, env=self._env,
                                     preexec_fn=die_with_parent())
        assert self.proc.stdout is not None and self.proc.stderr is not None
        # read stderr all along (keeping its tail): a child that logs into a full pipe blocks
        self._stderr_tail.clear()
        self._stderr_thread = threading.Thread(target=self._drain_stderr, args=(self.proc.stderr,),
                                               name="hil-softbus-stderr", daemon=True)
        self._stderr_thread.start()
        deadline = time.monotonic() + timeout
        import selectors
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        while time.monotonic() < deadline:
            if sel.select(timeout=max(0.0, deadline - time.monotonic())):
                line = self.proc.stdout.readline()
                if not line:
                    break
                match = re.search(r"listening on (\S+):(\d+)", line)
                if match:
                    self.port = int(match.group(2))
                    sel.close()
                    return self
        sel.close()
        self._end(timeout=5.0)
        detail = self._stderr()
        self.stop()
        raise SoftwareBusError(f"software bus process did not start: {detail}")

    def _drain_stderr(self, pipe: IO[str]) -> None:
        with contextlib.suppress(OSError, ValueError):
            for line in pipe:
                self._stderr_tail.append(line)

    def _stderr(self) -> str:
        if self._stderr_thread is not None:
            self._stderr_thread.join(5.0)
        return "".join(self._stderr_tail)[-2000:]

    def spec(self, channel: str = DEFAULT_CHANNEL) -> str:
        return f"socketcand:{self.host}:{self.port}/{channel}"

    def stats(self) -> dict[str, Any]:
        """The bus's counters (``< hil stats >`` over the control protocol)."""
        reply = control(self.host, self.port, ["stats"], token=self.control_token)
        return dict(json.loads(reply[len("< hil stats "):-2]))

    def _end(self, timeout: float) -> None:
        """End the child: close its stdin (it stops by itself), else terminate it, else kill
        it; its stdout and stderr stay readable."""
        if self.proc is None:
            return
        if self.proc.stdin is not None and not self.proc.stdin.closed:
            with contextlib.suppress(OSError):
                self.proc.stdin.close()
        if self.proc.poll() is not None:
            return
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.proc.wait(min(timeout, 2.0))
            return
        self.proc.terminate()
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout)

    def stop(self, timeout: float = 5.0) -> None:
        if self.proc is None:
            return
        try:
            self._end(timeout)
        finally:
            if self._stderr_thread is not None:
                self._stderr_thread.join(2.0)
            for pipe in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
                if pipe is not None and not pipe.closed:
                    with contextlib.suppress(OSError):
                        pipe.close()

    def __enter__(self) -> SoftwareBusProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

