"""Rig quantities: what a rig's devices tell the DUT and take from it, independent of any frame.

A :class:`Quantity` is one value on the rig's side of the bus contract: the set-point the
terminal sends, each row's sensed flow, the motor command the DUT writes. It has a unit, a
direction (``to_dut``: the rig publishes it; ``from_dut``: the rig takes it from the DUT), the
range and resolution the rig's physics needs, whether it is per row, and whether the rig needs
it at all (a ``required`` quantity that a binding leaves out is an error of ``hil profile
check``). A :class:`Contract` is a rig's list of them with the rig's default binding, databases
and nodes; a binding (:mod:`hil.contract.binding`) says on which frames they travel.

Example
-------
>>> q = Quantity("row_flow", "g/s", "to_dut", 0.0, 250.0, 0.01, "sensed flow", per_row=True)
>>> q.row_name(2)
'row_flow[2]'
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from hil.contract.units import canonical

__all__ = ["DIRECTIONS", "KINDS", "CanopenNode", "Contract", "Direction", "Kind", "Quantity"]

Direction = Literal["to_dut", "from_dut"]
DIRECTIONS: tuple[Direction, ...] = ("to_dut", "from_dut")
Kind = Literal["number", "flag", "enum", "counter"]
KINDS: tuple[Kind, ...] = ("number", "flag", "enum", "counter")


@dataclass(frozen=True)
class Quantity:
    """One rig quantity.

    Parameters
    ----------
    name : str
        ``lower_snake_case``; per-row quantities are addressed as ``name[row]`` (row from 1).
    unit : str
        A unit of :mod:`hil.contract.units` (``""`` for flags, enums and counters).
    direction : {"to_dut", "from_dut"}
        ``to_dut``: a rig device publishes it; ``from_dut``: the rig takes it from the DUT.
    minimum, maximum : float
        The range the rig produces (``to_dut``) or acts on (``from_dut``), in ``unit``.
    resolution : float
        The coarsest step that does not change the rig's results, in ``unit``.
    description : str
        One line: what it is, and where it comes from.
    per_row : bool, optional
        One value per row of the implement.
    required : bool, optional
        The rig cannot run a DUT without it (a binding must carry it).
    kind : {"number", "flag", "enum", "counter"}, optional
        ``flag``: 0/1; ``enum``: one of :attr:`values`; ``counter``: a rolling counter that
        wraps at ``maximum + 1``.
    values : mapping of int to str, optional
        The names of an enum's values.
    event_driven : bool, optional
        Sent when the rig's model produces it (a flow module's window), not on a period the
        binding may choose: its carrier's cycle time must be the rig's.

    Raises
    ------
    ValueError
        A bad name, direction, kind, unit, range or resolution.
    """

    name: str
    unit: str
    direction: Direction
    minimum: float
    maximum: float
    resolution: float
    description: str
    per_row: bool = False
    required: bool = False
    kind: Kind = "number"
    values: Mapping[int, str] = field(default_factory=dict)
    event_driven: bool = False

    def __post_init__(self) -> None:
        if not self.name.replace("_", "a").isalnum() or not self.name[:1].islower():
            raise ValueError(f"quantity names are lower_snake_case, got {self.name!r}")
        if self.direction not in DIRECTIONS:
            raise ValueError(f"{self.name}: direction must be one of {DIRECTIONS}")
        if self.kind not in KINDS:
            raise ValueError(f"{self.name}: kind must be one of {KINDS}")
        canonical(self.unit)
        if not self.minimum <= self.maximum:
            raise ValueError(f"{self.name}: minimum {self.minimum} is above maximum "
                             f"{self.maximum}")
        if not self.resolution > 0:
            raise ValueError(f"{self.name}: resolution must be > 0")
        if self.kind == "enum" and not self.values:
            raise ValueError(f"{self.name}: an enum needs its values")

    def row_name(self, row: int | None) -> str:
        """``name`` or ``name[row]``, as errors and the docs address it."""
        return f"{self.name}[{row}]" if row is not None else self.name


@dataclass(frozen=True)
class CanopenNode:
    """A CANopen node the rig plays, described by an EDS."""

    name: str
    node_id: int
    eds: Path


@dataclass(frozen=True)
class Contract:
    """A rig's bus contract: its quantities, default binding, databases and nodes.

    A rig builds it from its config (a profile's ``[rig]`` overrides applied): see
    :func:`hil.contract.registry.rig_contract`.

    Parameters
    ----------
    rig : str
        The rig's name.
    quantities : tuple of Quantity
        Every quantity the rig's devices publish or take.
    rows : int
        The implement's rows (the per-row quantities' count).
    binding_file : Path
        The binding in force: the rig's default one beside its DBC, or a profile's.
    default_binding_file : Path
        The rig's own binding (of its own DBC).
    dut_node : str
        The DUT's node name in the rig's own database.
    canopen_nodes : tuple of CanopenNode
        The CANopen nodes the rig plays.
    bitrate_bps : int
        The bus's bit rate.
    command_ids : frozenset of int
        The frames the DUT sends once per control period (after SYNC in lockstep).
    dut_is_nmt_master : bool
        The DUT starts the rig's CANopen nodes.
    node_ids : mapping of str to int
        CAN ids the rig's own nodes use whatever the binding (CANopen heartbeats, PDOs of its
        EDS devices, SYNC, NMT): a bound message on one of them clashes.
    periods_ms : mapping of str to float
        The rig's own period of the quantities it publishes on a period (the default when the
        binding and its database give none), and the fixed period of event-driven ones.
    dispersion_file : Path or None
        The rig's shipped dispersion file for ``hil campaign``.
    control_period_ms : float
        The SYNC period.
    physics_period_ms : float
        The physics step: the rig sends on these steps only.
    command_quantities : tuple of str
        The quantities the DUT sends once per control period: their frames end a lockstep
        step (the rig's command ids under any binding).
    fixed_ids : mapping of str to int
        Quantities whose frame id the wiring fixes whatever the database (a CANopen device's
        RPDO as its EDS maps it, the DUT's heartbeat at 0x700 + node id).
    fixed_id_reasons : mapping of str to str
        Why, per quantity of :attr:`fixed_ids`.
    dut_node_id : int
        The DUT's node id in the rig's wiring.
    """

    rig: str
    quantities: tuple[Quantity, ...]
    rows: int
    binding_file: Path
    default_binding_file: Path
    dut_node: str
    canopen_nodes: tuple[CanopenNode, ...]
    bitrate_bps: int
    command_ids: frozenset[int]
    dut_is_nmt_master: bool = False
    node_ids: Mapping[str, int] = field(default_factory=dict)
    periods_ms: Mapping[str, float] = field(default_factory=dict)
    dispersion_file: Path | None = None
    control_period_ms: float = 100.0
    physics_period_ms: float = 1.0
    command_quantities: tuple[str, ...] = ()
    fixed_ids: Mapping[str, int] = field(default_factory=dict)
    fixed_id_reasons: Mapping[str, str] = field(default_factory=dict)
    dut_node_id: int = 0

    def quantity(self, name: str) -> Quantity:
        """The quantity called ``name``.

        Raises
        ------
        KeyError
            No such quantity (the message lists them).
        """
        for q in self.quantities:
            if q.name == name:
                return q
        raise KeyError(f"the {self.rig} rig has no quantity {name!r} (known: "
                       f"{', '.join(q.name for q in self.quantities)})")

    def names(self) -> tuple[str, ...]:
        """Every quantity's name, in declaration order."""
        return tuple(q.name for q in self.quantities)


#: what a rig registers: ``describe(config overrides, their source)`` → its contract
Describe = Callable[[Mapping[str, Any], str], Contract]
