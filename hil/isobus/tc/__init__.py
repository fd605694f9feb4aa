"""The Task Controller server of ISO 11783-10 (version 4) and its seams.

:class:`TaskControllerServer` runs on an :class:`~hil.isobus.port.IsobusPort`; set-points come
from a :data:`SetpointSource` (prescription maps and coverage plug in there); stored pools live
in a :class:`PoolStore` that outlives a restart; what the TC received is in its ``values``,
``acknowledgements`` and ``events``.
"""

from hil.isobus.tc.records import Event, EventKind, LoggedValue, ReceivedAcknowledge
from hil.isobus.tc.server import (
    CLIENT_TIMEOUT_S,
    STATUS_PERIOD_S,
    ClientSession,
    ServerOptions,
    TaskControllerServer,
)
from hil.isobus.tc.setpoints import (
    SetpointRequest,
    SetpointSource,
    constant_setpoints,
    no_setpoints,
)
from hil.isobus.tc.store import PoolStore, StoredPool
from hil.isobus.tc.triggers import TriggerPlan

__all__ = [
    "CLIENT_TIMEOUT_S",
    "STATUS_PERIOD_S",
    "ClientSession",
    "Event",
    "EventKind",
    "LoggedValue",
    "PoolStore",
    "ReceivedAcknowledge",
    "ServerOptions",
    "SetpointRequest",
    "SetpointSource",
    "StoredPool",
    "TaskControllerServer",
    "TriggerPlan",
    "constant_setpoints",
    "no_setpoints",
]
