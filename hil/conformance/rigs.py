"""Where each rig keeps its bus databases: the DBC, the CANopen nodes it plays (EDS), its
bit rate. A table by rig name that a new rig adds itself to (:func:`register`); the core never
imports a plant unless a run of that rig asks for it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class CanopenNode:
    """A CANopen node the rig plays, described by an EDS."""

    name: str
    node_id: int
    eds: Path


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
    if key not in _RIGS:
        raise KeyError(f"no bus databases registered for the rig {rig!r} "
                       f"(known: {', '.join(sorted(_RIGS))})")
    return _RIGS[key](overrides or {}, source)


def _fertilizer(overrides: Mapping[str, Any], source: str) -> RigBus:
    from plant_emulators.fertilizer.config import load_rig_config

    wiring = load_rig_config(overrides=overrides, source=source).wiring
    analog = wiring.analog_output_node_id
    return RigBus(dbc=Path(wiring.dbc_file), dut_node="Controller",
                  canopen_nodes=(CanopenNode("analog output module", analog,
                                             Path(wiring.analog_output_eds_file)),),
                  bitrate_bps=wiring.bitrate_bps, command_ids=frozenset({0x200 + analog}))


def _sowing_depth(overrides: Mapping[str, Any], source: str) -> RigBus:
    from plant_emulators.sowing_depth.config import load_rig_config
    from plant_emulators.sowing_depth.frames import DBC_PATH, EDS_PATH

    wiring = load_rig_config(overrides=overrides, source=source).wiring
    drive = wiring.drive_node_id
    return RigBus(dbc=DBC_PATH, dut_node="DepthController",
                  canopen_nodes=(CanopenNode("servo drive", drive, EDS_PATH),),
                  bitrate_bps=wiring.bitrate_bit_per_s,
                  command_ids=frozenset({0x200 + drive, 0x300 + drive}),
                  # the depth controller starts the drive (NMT start when its heartbeat shows
                  # it is not Operational): the DBC is J1939 only, the drive is its EDS's
                  dut_is_nmt_master=True)


register("fertilizer", _fertilizer)
register("sowing_depth", _sowing_depth)
