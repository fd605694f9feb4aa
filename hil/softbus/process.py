"""The software bus in a child process (``python -m hil bus serve``), started and stopped from
this one.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from hil.softbus.control import control
from hil.softbus.settings import (
    BUSY_POLL_ENV,
    DEFAULT_CHANNEL,
    SoftwareBusError,
    check_loopback,
)


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
                      "--port", str(port), "--seed", str(seed)]
        if bitrate:
            self._args += ["--bitrate", str(bitrate)]
        if log_path:
            self._args += ["--log", str(log_path)]
        self._env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        if busy_poll_us is not None:
            self._env[BUSY_POLL_ENV] = str(max(0.0, busy_poll_us))
        self.proc: subprocess.Popen[str] | None = None

    def start(self, timeout: float = 10.0) -> SoftwareBusProcess:
        self.proc = subprocess.Popen(self._args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, env=self._env)
        assert self.proc.stdout is not None
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

    def _stderr(self) -> str:
        if self.proc is None or self.proc.stderr is None:
            return ""
        with contextlib.suppress(Exception):
            return self.proc.stderr.read()[-2000:]
        return ""

    def spec(self, channel: str = DEFAULT_CHANNEL) -> str:
        return f"socketcand:{self.host}:{self.port}/{channel}"

    def stats(self) -> dict[str, Any]:
        """The bus's counters (``< hil stats >`` over the control protocol)."""
        reply = control(self.host, self.port, ["stats"])
        return dict(json.loads(reply[len("< hil stats "):-2]))

    def _end(self, timeout: float) -> None:
        """Terminate the child (kill it if it does not go), leaving its pipes readable."""
        if self.proc is None or self.proc.poll() is not None:
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
            for pipe in (self.proc.stdout, self.proc.stderr):
                if pipe is not None and not pipe.closed:
                    pipe.close()

    def __enter__(self) -> SoftwareBusProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

