"""Where each rig keeps its bus databases: the DBC, the CANopen nodes it plays (EDS), its
bit rate, as conformance needs them.

They come from the rig's own bus contract (:func:`hil.contract.registry.rig_contract`, through
the rig's registration): the core imports no rig. The database is the binding's in force, so a
DUT bound to its own database is judged against it. :func:`register` still lets a test or a
tool put a rig here directly.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.contract.binding import load_binding
from hil.contract.quantity import CanopenNode
from hil.contract.registry import rig_contract


@dataclass(frozen=True)
class RigBus:
    """A rig's bus databases, with the rig's config (a profile's ``[rig]`` overrides) applied.

    Attributes
    ----------
    dbc : Path
        The rig's message database.
    dut_node : str
        The DUT's node name in the DBC, used when no DBC message carries the DUT's heartbeat
        (0x700 + node id), which otherwise names it.
    canopen_nodes : tuple of CanopenNode
        The rig's CANopen nodes (their EDS declare the PDOs the DUT sends them, and whether
        they consume its heartbeat, object 0x1016).
    bitrate_bps : int
        The bus's bit rate.
    command_ids : frozenset of int
        The frames the DUT sends once per control period, on SYNC (a profile's
        ``wiring.command_ids`` take precedence).
    dut_is_nmt_master : bool
        The DUT is the NMT master of the rig's CANopen nodes (it may send NMT commands,
        COB-ID 0x000, two bytes); else only the DBC can declare them for it.
    """

    dbc: Path
    dut_node: str
    canopen_nodes: tuple[CanopenNode, ...]
    bitrate_bps: int
    command_ids: frozenset[int]
    dut_is_nmt_master: bool = False


_RIGS: dict[str, Callable[[Mapping[str, Any], str], RigBus]] = {}


def register(name: str, describe: Callable[[Mapping[str, Any], str], RigBus]) -> None:
    """Add a rig: ``describe(config overrides, their source)`` gives its :class:`RigBus`."""
    _RIGS[name.replace("-", "_")] = describe


def rig_bus(rig: str, overrides: Mapping[str, Any] | None = None, source: str = "") -> RigBus:
    """The bus databases of ``rig`` with ``overrides`` of its config applied.

    Raises
    ------
    KeyError
        No rig of that name is registered.
    """
    key = rig.replace("-", "_")
    if key in _RIGS:
        return _RIGS[key](overrides or {}, source)
    from hil.rig.registry import available_rigs

    if key not in available_rigs():
        raise KeyError(f"no bus databases registered for the rig {rig!r} "
                       f"(known: {', '.join(available_rigs())})")
    contract = rig_contract(key, overrides, source)
    binding = load_binding(contract.binding_file)
    return RigBus(dbc=binding.database, dut_node=binding.dut_node or contract.dut_node,
                  canopen_nodes=contract.canopen_nodes, bitrate_bps=contract.bitrate_bps,
                  command_ids=contract.command_ids,
                  dut_is_nmt_master=contract.dut_is_nmt_master)


__all__ = ["CanopenNode", "RigBus", "register", "rig_bus"]
