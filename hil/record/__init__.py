"""What a run leaves behind: bus logs, traces and ``record.json``.

Use :class:`Recorder` as a context manager: whatever happens inside (an exception, Ctrl-C,
SIGTERM through the CLI), everything recorded so far is written on the way out.
"""

from hil.record.buslog import BusLog
from hil.record.recorder import Recorder, Verdict
from hil.record.traces import TraceSet, load_traces

__all__ = ["BusLog", "Recorder", "TraceSet", "Verdict", "load_traces"]
