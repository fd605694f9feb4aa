"""Frames a scripted peer sends to take part on the bus: its address claims."""

from __future__ import annotations

import can

from hil.isobus.can_id import make_frame
from hil.isobus.port import GLOBAL_ADDRESS
from hil.isobus.tp_messages import PGN_ADDRESS_CLAIMED

#: NAMEs of scripted peers: identity number = address, function 130, device class 5 (above
#: the rig's NAMEs, so a scripted claim never takes one of the rig's addresses)
PEER_NAME_BASE = 0xA000_8000_0000_0000


def claim(address: int, name: int | None = None) -> can.Message:
    """The address-claimed message of ``address`` with ``name`` (default: one per address)."""
    value = PEER_NAME_BASE | address if name is None else name
    return make_frame(6, PGN_ADDRESS_CLAIMED, address, GLOBAL_ADDRESS,
                      value.to_bytes(8, "little"))


def claims(*addresses: int, at_s: float = 0.0) -> list[tuple[float, can.Message]]:
    """A ScriptedNode script claiming each of ``addresses`` at ``at_s``."""
    return [(at_s, claim(a)) for a in addresses]
