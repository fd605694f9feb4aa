"""Dask worker preload: local workers ignore SIGINT, so Ctrl-C reaches the campaign alone.

A terminal's Ctrl-C goes to its whole process group, the local Dask workers included; each
would die printing a KeyboardInterrupt traceback (and its nanny another), over the campaign's
own one-line "interrupted". The campaign stops its workers itself when it is interrupted
(closing the cluster), so a worker has nothing to do with the signal. Loaded through Dask's
``distributed.worker.preload`` by :func:`hil.campaign.engine.dask_client` for the workers of a
``LocalCluster`` it starts (restarted workers too); the samples' own processes run in sessions
of their own and never see the terminal's signals.
"""

from __future__ import annotations

import logging
import signal
import threading
from typing import Any

#: what a worker logs when the scheduler went away first, as it does when a campaign stops
#: its cluster: the end of the campaign, not an error
_SHUTDOWN_NOISE = ("CommClosedError", "StreamClosedError")


class _ShutdownNoise(logging.Filter):
    """Drops a worker's "lost the scheduler" errors (with their traceback) once the scheduler
    is closing; any other error is still printed."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        chain = []
        while exc is not None:
            chain.append(type(exc).__name__)
            exc = exc.__cause__ or exc.__context__
        return not any(name in _SHUTDOWN_NOISE for name in chain)


def dask_setup(worker: Any) -> None:
    """Ignore SIGINT in this worker process (Dask calls this as the worker starts), and drop
    the errors a worker logs when its scheduler closes before it."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in ("distributed.worker", "distributed.core", "distributed.nanny"):
        logging.getLogger(name).addFilter(_ShutdownNoise())
