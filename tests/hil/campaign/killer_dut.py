"""An in-process DUT that kills the process it runs in (tests/hil/campaign/test_dead_worker.py).

A segfaulting native extension or an ``os._exit`` in a controller does the same to a Dask
worker that runs a sample in-process.
"""

from __future__ import annotations

import os
import signal


def make(**params: object) -> None:
    """Kill this process at once, as the DUT is built."""
    os.kill(os.getpid(), signal.SIGKILL)
