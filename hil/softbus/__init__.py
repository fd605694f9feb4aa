"""The software bus: a loopback CAN bus server speaking the socketcand protocol.

For machines without kernel CAN (CI containers, macOS). python-can clients join it with
``interface="socketcand"``; a C program joins it with a few dozen lines of socket code.
See :mod:`hil.softbus.server` for the server, :mod:`hil.softbus.timing` for bit-rate pacing
and :mod:`hil.softbus.faults` for fault injection.
"""

from hil.softbus.faults import FaultKind, FaultRule
from hil.softbus.server import DEFAULT_PORT, SoftwareBus, SoftwareBusProcess

__all__ = ["DEFAULT_PORT", "FaultKind", "FaultRule", "SoftwareBus", "SoftwareBusProcess"]
