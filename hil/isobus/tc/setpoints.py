"""The seam between the TC and whatever decides set-points (prescription maps, coverage).

The server asks a :data:`SetpointSource` for every settable process data entity (a DPD with the
settable property) of every active client, on every tick; the source answers with the raw value
in the DDI's units (see :mod:`hil.isobus.ddi`) or ``None`` for "nothing to send". The server sends
a value command when the answer changes (and again every ``setpoint_refresh_s`` if set). Section
states travel as the condensed work state set-points (DDI 290-305, 16 sections of 2 bits each;
:func:`hil.isobus.ddi.pack_condensed_work_state`), the rate as e.g. DDI 6 (mg/m²).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class SetpointRequest:
    """What the server asks the source about.

    Attributes
    ----------
    client_address : int
        The client's source address.
    client_name : int or None
        Its NAME, when the network layer knows it.
    element : int
        Element number of the settable entity in the client's DDOP.
    ddi : int
        Its DDI.
    time_s : float
        Run time of the tick.
    """

    client_address: int
    client_name: int | None
    element: int
    ddi: int
    time_s: float


SetpointSource = Callable[[SetpointRequest], int | None]
"""Answers a :class:`SetpointRequest` with a raw value or ``None``."""


def no_setpoints(request: SetpointRequest) -> int | None:
    """The source of a TC that sends no set-points (documentation only, TC-BAS)."""
    return None


def constant_setpoints(values: dict[int, int]) -> SetpointSource:
    """A source giving the same raw value per DDI on every element that has it.

    >>> src = constant_setpoints({6: 25000})
    >>> src(SetpointRequest(0x81, None, 2, 6, 0.0)), src(SetpointRequest(0x81, None, 2, 7, 0.0))
    (25000, None)
    """
    def source(request: SetpointRequest) -> int | None:
        return values.get(request.ddi)
    return source
