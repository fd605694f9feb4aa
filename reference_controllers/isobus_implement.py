"""What the reference controllers' ISOBUS modes share: one implement control function on its
own network with a Task Controller client (the fertilizer's, issue 27; the depth's, issue 42).

:class:`TcImplement` holds the :class:`~hil.isobus.network.IsobusNetwork`, the function's
port and its :class:`~hil.isobus.tc_client.TaskControllerClient`, and what the network answered
to the frames received since the last control step: a controller sends only in its step (as a
firmware's task does; ISO 11783-3's response time is 200 ms), first those answers, then what is
due at the step's time (:meth:`TcImplement.take`). The NAME (:func:`implement_name`) and the
checks of the preferred address and identity number (:func:`check_address`) are the same for
both; the DDOP, the set-points and what is reported are each controller's.
"""

from __future__ import annotations

from collections.abc import Callable

import can

from hil.isobus.ddop import ObjectPool
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.tc_client import SetpointHandler, TaskControllerClient, ValueReader

__all__ = ["INDUSTRY_GROUP_AGRICULTURE", "TcImplement", "check_address", "implement_name"]

INDUSTRY_GROUP_AGRICULTURE = 2


def check_address(address: float, identity_number: float) -> None:
    """Raise ``ValueError`` naming a preferred source address outside 0 .. 253 or an identity
    number that is not a 21-bit integer."""
    if not (address == int(address) and 0 <= address <= 0xFD):
        raise ValueError(f"address must be an integer 0 .. 253, got {address}")
    if not (identity_number == int(identity_number) and 0 <= identity_number < 1 << 21):
        raise ValueError(f"identity_number must be an integer below 2^21, "
                         f"got {identity_number}")


def implement_name(identity_number: int, *, device_class: int, function: int) -> IsobusName:
    """An agricultural implement's self-configurable NAME (manufacturer code 0)."""
    return IsobusName(identity_number=identity_number, manufacturer_code=0,
                      function=function, device_class=device_class,
                      industry_group=INDUSTRY_GROUP_AGRICULTURE, self_configurable=True)


class TcImplement:
    """One implement control function on its own network, with a TC client on its port.

    Parameters
    ----------
    network_name : str
        The network's name (the controller's, for logs).
    name : IsobusName
        The function's NAME.
    address : int
        Its preferred source address.
    label : str
        What the function is (for logs and errors).
    pool : ObjectPool
        Its DDOP.
    on_setpoint, read_value, on_connection
        The controller's side of the client (:class:`~hil.isobus.tc_client.TaskControllerClient`).
    """

    def __init__(self, *, network_name: str, name: IsobusName, address: int, label: str,
                 pool: ObjectPool,
                 on_setpoint: SetpointHandler, read_value: ValueReader,
                 on_connection: Callable[[bool, float], None]) -> None:
        self.network = IsobusNetwork(name=network_name)
        self.port = self.network.add(name, address, label)
        self.client = TaskControllerClient(self.port, pool, on_setpoint=on_setpoint,
                                           read_value=read_value, on_connection=on_connection)
        self.port.run(self.client)
        #: what the network answered to frames received since the last step
        self._replies: list[can.Message] = []

    def receive(self, msg: can.Message, time_s: float) -> None:
        """Take an extended frame at ``time_s``; the answers wait for :meth:`take`."""
        self._replies.extend(self.network.on_frame(msg, time_s))

    def take(self, time_s: float) -> list[can.Message]:
        """The step's ISOBUS frames: the answers since the last step, then what is due."""
        out = self._replies + self.network.emit(time_s)
        self._replies = []
        return out
