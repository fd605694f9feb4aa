"""A signal-level FMU (FMI 2.0 or 3.0 co-simulation) as a controller on the rig's bus.

The FMU has real, integer and boolean inputs and outputs and knows nothing of CAN. The profile
binds each FMU variable to a rig quantity (``[fmu.variables] "FlowRow1" = "row_flow[1]"``), and
the frames are those of the binding in force (the DUT's own database, or the rig's): the same
:class:`~hil.contract.codec.ContractCodec` that the rig's devices use decodes every frame the
rig sends into quantities, and encodes what the FMU outputs into the DUT's frames. So the FMU
sees sensor values and commands actuators while the rig's devices still speak the contract on
the bus.

One ``doStep`` per control period, at each SYNC: the FMU's inputs take the latest value of
their quantity (converted from the quantity's unit to the variable's), the FMU steps from the
SYNC's time to the next, and its outputs (converted back) go out in the frames that carry them,
each frame at its cycle time (the binding's, the database's, else the rig's), the command
frames (``wiring.command_ids``) last. What a CAN node does besides its application is the
harness's: the boot-up frame at start, the heartbeat (``dut_nmt_state`` operational) and the
rolling counters of the frames it sends, unless the FMU outputs them itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import can

from hil.contract.codec import ContractCodec
from hil.contract.quantity import Contract, Quantity
from hil.dut.inprocess import Controller
from hil.errors import ConfigError, FrameError
from hil.fmi.fmufile import FmuFile
from hil.fmi.instance import FmuInstance

__all__ = ["SignalBinding", "SignalFmuController", "parse_quantity", "variable_unit"]

SYNC_ID = 0x080
NMT_BOOT_UP, NMT_OPERATIONAL = 0, 5
HEARTBEAT = "dut_nmt_state"


@dataclass(frozen=True)
class SignalBinding:
    """One FMU variable on one rig quantity (of one row), with the unit factor.

    ``value_variable = value_quantity * factor``.
    """

    variable: Any
    quantity: Quantity
    row: int | None
    factor: float

    @property
    def key(self) -> str:
        return self.quantity.row_name(self.row)


def parse_quantity(text: str, contract: Contract) -> tuple[Quantity, int | None]:
    """``"row_flow[2]"`` → (the quantity, 2); ``"target_flow"`` → (it, None).

    Raises
    ------
    ConfigError
        No such quantity, a row on a quantity that has none, a row out of range, or a per-row
        quantity without its row (``key`` left for the caller to set).
    """
    name, _, rest = text.partition("[")
    try:
        quantity = contract.quantity(name.strip())
    except (KeyError, ConfigError):
        raise ConfigError(f"the {contract.rig} rig has no quantity {name.strip()!r} (see "
                          f"docs/reference/rig-quantities.md)") from None
    if not rest:
        if quantity.per_row:
            raise ConfigError(f"{quantity.name} has one value per row: name the row "
                              f"({quantity.name}[1] .. {quantity.name}[{contract.rows}])")
        return quantity, None
    if not rest.endswith("]") or not rest[:-1].strip().isdigit():
        raise ConfigError(f"{text!r} is not quantity or quantity[row]")
    row = int(rest[:-1])
    if not quantity.per_row:
        raise ConfigError(f"{quantity.name} is not per row: drop [{row}]")
    if not 1 <= row <= contract.rows:
        raise ConfigError(f"row {row} of {quantity.name}: the rig has rows 1..{contract.rows}")
    return quantity, row


def variable_unit(var: Any) -> str:
    """The FMU variable's unit (its own, else its declared type's), "" when it has none."""
    unit = getattr(var, "unit", None)
    if not unit and getattr(var, "declaredType", None) is not None:
        unit = getattr(var.declaredType, "unit", None)
    return str(unit or "")


class SignalFmuController(Controller):
    """One signal-level FMU on the rig's bus (see the module's description).

    Parameters
    ----------
    fmu : FmuFile
        The FMU.
    codec : ContractCodec
        The binding in force (the DUT's database), rig quantities to frames and back.
    inputs, outputs : list of SignalBinding
        The FMU's bound inputs and outputs.
    period_s : float
        The control period.
    command_ids : collection of int
        The frames that close a lockstep step: sent last.
    heartbeat_period_s : float
        The heartbeat's period when the binding gives none.
    parameters : dict, optional
        Values for the FMU's parameters by variable name.
    name : str, optional
        The instance's name.
    """

    def __init__(self, fmu: FmuFile, codec: ContractCodec, *, inputs: list[SignalBinding],
                 outputs: list[SignalBinding], period_s: float, command_ids: frozenset[int],
                 heartbeat_period_s: float, parameters: dict[str, Any] | None = None,
                 name: str = "fmu") -> None:
        self.fmu = fmu
        self.codec = codec
        self.inputs = inputs
        self.outputs = outputs
        self.period_s = period_s
        self.command_ids = command_ids
        self.parameters = dict(parameters or {})
        self.name = name
        self.inst: FmuInstance | None = None
        self.env_parameters: dict[str, str] = {}
        self.latest: dict[str, Any] = {}
        self.steps = 0
        self.undecodable = 0
        contract = codec.contract
        sent = {b.quantity.name for b in outputs}
        #: from_dut quantities the harness fills: the heartbeat and rolling counters
        self.own = [q for q in contract.quantities if q.direction == "from_dut"
                    and q.name not in sent and codec.carries(q.name)
                    and (q.name == HEARTBEAT or q.kind == "counter")]
        self.counters: dict[str, int] = {}
        #: per (row, message) group of quantities, and every how many steps it goes out
        self._groups = self._plan(heartbeat_period_s)

    def _plan(self, heartbeat_period_s: float) -> list[tuple[int | None, tuple[str, ...], int]]:
        by_frame: dict[tuple[int | None, int], list[str]] = {}
        names = [(b.quantity, b.row) for b in self.outputs] + [(q, None) for q in self.own]
        for quantity, row in names:
            if not self.codec.carries(quantity.name):
                continue
            frame = self.codec.frame_id(quantity.name, row)
            group = by_frame.setdefault((row, frame), [])
            if quantity.name not in group:
                group.append(quantity.name)
        plan = []
        for (row, frame), group in by_frame.items():
            if frame in self.command_ids:
                every = 1
            else:
                cycle = self.codec.cycle_ms(group[0], row)
                period = cycle / 1000.0 if cycle else (
                    heartbeat_period_s if HEARTBEAT in group else self.period_s)
                every = max(1, round(period / self.period_s))
            plan.append((row, tuple(group), every))
        # command frames last, the rest in the order of their ids
        plan.sort(key=lambda p: (self.codec.frame_id(p[1][0], p[0]) in self.command_ids,
                                 self.codec.frame_id(p[1][0], p[0])))
        return plan

    # --- life cycle ----------------------------------------------------------------------
    def configure(self, env: dict[str, str]) -> None:
        """The rig's offers (a serial port): the FMU's string parameters of that name."""
        from hil.fmi.parameters import environment_parameters

        self.env_parameters = environment_parameters(self.fmu, env)

    def on_start(self) -> list[can.Message]:
        from hil.fmi.parameters import apply_parameters

        self.close()
        inst = FmuInstance(self.fmu, self.name)
        self.inst = inst
        apply_parameters(inst, self.fmu, {**self.env_parameters, **self.parameters})
        inst.initialize(0.0)
        self.latest = {}
        self.steps = 0
        self.counters = {}
        if self.codec.carries(HEARTBEAT):
            return self.codec.encode({HEARTBEAT: NMT_BOOT_UP})
        return []

    def close(self) -> None:
        """Free the FMU instance (safe to call twice)."""
        if self.inst is not None:
            self.inst.close()
            self.inst = None

    # --- frames ----------------------------------------------------------------------------
    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.is_error_frame:
            return []
        if not msg.is_extended_id and msg.arbitration_id == SYNC_ID:
            return self._step()
        try:
            values = self.codec.decode(msg)
        except FrameError:
            self.undecodable += 1
            return []
        if values:
            self.latest.update(values)
        return []

    def silent(self, msg: can.Message) -> bool:
        """Whether the controller never answers ``msg`` (every frame but SYNC: they only set
        the inputs of the next step), so the FMU host need not wait for its answer."""
        return msg.is_error_frame or msg.is_extended_id or msg.arbitration_id != SYNC_ID

    def _step(self) -> list[can.Message]:
        inst = self.inst
        assert inst is not None, "on_frame before on_start"
        t = self.steps * self.period_s
        for b in self.inputs:
            value = self.latest.get(b.key)
            if value is not None:
                inst.set(b.variable, value * b.factor if b.factor != 1.0 else value)
        inst.do_step(t + self.period_s)
        values: dict[tuple[int | None, str], Any] = {}
        for b in self.outputs:
            raw = inst.get(b.variable)
            value = raw / b.factor if b.factor != 1.0 else raw
            if isinstance(value, float) and not math.isfinite(value):
                raise FrameError(f"FMU output {b.variable.name} is {value} at t = {t:.3f} s")
            values[(b.row, b.quantity.name)] = value
        out: list[can.Message] = []
        for row, group, every in self._groups:
            if self.steps % every:
                continue
            frame_values = {name: self._value(values, row, name) for name in group}
            out += self.codec.encode(frame_values, row=row, strict=False)
        self.steps += 1
        return out

    def _value(self, values: dict[tuple[int | None, str], Any], row: int | None,
               name: str) -> Any:
        if (row, name) in values:
            return values[(row, name)]
        if name == HEARTBEAT:
            return NMT_OPERATIONAL
        wrap = int(self.codec.contract.quantity(name).maximum) + 1
        count = (self.counters.get(name, -1) + 1) % wrap
        self.counters[name] = count
        return count
