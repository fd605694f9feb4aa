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

import signal
import threading
from typing import Any


def dask_setup(worker: Any) -> None:
    """Ignore SIGINT in this worker process (Dask calls this as the worker starts)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
