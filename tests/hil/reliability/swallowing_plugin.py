"""A pytest plugin (loaded through ``PYTEST_PLUGINS``) that loses a SIGINT's KeyboardInterrupt
the way a finalizer or a library's catch-all does: the signal arrives inside a test and its
exception is swallowed. The command must still end as interrupted (exit 130), never 0."""

from __future__ import annotations

import contextlib
import os
import signal
import time

_sent = False


def pytest_runtest_call() -> None:
    global _sent
    if _sent:
        return
    _sent = True
    with contextlib.suppress(KeyboardInterrupt):   # what "Exception ignored in ..." does
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(1.0)                           # the handler runs here, then is swallowed
