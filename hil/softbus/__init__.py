"""The software bus: a loopback CAN bus server speaking the socketcand protocol.

For machines without kernel CAN (CI containers, macOS). python-can clients join it with
``interface="socketcand"``; a C program joins it with a few dozen lines of socket code.
See :mod:`hil.softbus.server` for the server (the facade over :mod:`~hil.softbus.transport`,
:mod:`~hil.softbus.session`, :mod:`~hil.softbus.core`, :mod:`~hil.softbus.local` and
:mod:`~hil.softbus.process`), :mod:`hil.softbus.control` for the control connection and who may
send control commands, :mod:`hil.softbus.timing` for bit-rate pacing and
:mod:`hil.softbus.faults` for fault injection.
"""

from hil.softbus.faults import FaultKind, FaultRule
from hil.softbus.server import DEFAULT_PORT, SoftwareBus, SoftwareBusProcess

__all__ = ["DEFAULT_PORT", "FaultKind", "FaultRule", "SoftwareBus", "SoftwareBusProcess"]
