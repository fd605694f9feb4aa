"""A rig file checked against its FMU and its DBC, and its bus contract.

:func:`build_plan` resolves every device signal to a rig quantity, a DBC signal and an FMU
variable, refusing whatever does not fit (naming the rig file's key); :meth:`RigPlan.contract`
is the rig's :class:`~hil.contract.quantity.Contract` and :meth:`RigPlan.binding` the binding of
those quantities to the DBC's frames, so frames are encoded and decoded by the same
:class:`~hil.contract.codec.ContractCodec` as the built-in rigs'. The binding is also written
as an ordinary binding file (:func:`binding_path`) for the tools that read one (bus
conformance, ``hil profile check``).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.contract.binding import Binding, parse_binding
from hil.contract.database import BusDatabase
from hil.contract.quantity import CanopenNode, Contract, Quantity
from hil.contract.units import canonical, factor
from hil.errors import ConfigError, FrameError
from hil.ownrig.config import (
    LoadedRigFile,
    ReceivedMessage,
    ReceivedSignal,
    SentMessage,
    SentSignal,
    snake,
)
from hil.ownrig.fmu import FmuDescription, VariableRef

READABLE = ("output", "local", "parameter", "calculatedParameter")


@dataclass(frozen=True)
class SentPlan:
    """One signal a device sends: its quantity, DBC signal and source."""

    quantity: str
    signal: str
    spec: SentSignal
    unit: str
    source: VariableRef | None
    key: str


@dataclass(frozen=True)
class ReceivedPlan:
    """One signal a device receives: its quantity, DBC signal and the FMU input it drives."""

    quantity: str
    signal: str
    spec: ReceivedSignal
    unit: str
    target: VariableRef
    key: str


@dataclass(frozen=True)
class MessagePlan:
    """A message of a device, its frame id and period, and its signals."""

    device: str
    message: str
    frame_id: int
    period_s: float | None
    spec: SentMessage | ReceivedMessage
    sent: tuple[SentPlan, ...] = ()
    received: tuple[ReceivedPlan, ...] = ()


@dataclass(frozen=True)
class ControlledPlan:
    """A controlled quantity resolved: target input, sensed quantity, truth variable."""

    name: str
    target: str
    sensed: str
    truth: VariableRef
    unit: str
    band: float
    spec: Any


@dataclass
class RigPlan:
    """Everything a run of the rig needs, resolved and checked."""

    loaded: LoadedRigFile
    fmu: FmuDescription
    database: BusDatabase
    sent: list[MessagePlan]
    received: list[MessagePlan]
    inputs: dict[str, tuple[str, VariableRef | None]]
    controlled: dict[str, ControlledPlan]
    quantities: tuple[Quantity, ...]
    carriers: dict[str, dict[str, Any]]

    @property
    def name(self) -> str:
        return self.loaded.spec.name

    def watched(self) -> list[VariableRef]:
        """Every FMU scalar the rig reads: the sensed sources, the truths and every output."""
        refs: dict[str, VariableRef] = {}
        for message in self.sent:
            for s in message.sent:
                if s.source is not None:
                    refs.setdefault(s.source.text, s.source)
        for c in self.controlled.values():
            refs.setdefault(c.truth.text, c.truth)
        for ref in truth_outputs(self.fmu):
            refs.setdefault(ref.text, ref)
        return list(refs.values())

    def binding(self) -> Binding:
        """The binding of the rig's quantities to the DBC (the one binding layer)."""
        return parse_binding({"rig": self.name, "database": str(self.loaded.dbc),
                              "dut_node": self.loaded.spec.dut_node,
                              "quantities": self.carriers},
                             source=self.loaded.source, base=self.loaded.path.parent,
                             path=binding_path(self))

    def command_ids(self) -> frozenset[int]:
        return frozenset(m.frame_id for m in self.received
                         if isinstance(m.spec, ReceivedMessage) and m.spec.command)

    def contract(self) -> Contract:
        """The rig's bus contract (its quantities, binding file, nodes, periods)."""
        spec = self.loaded.spec
        path = binding_path(self)
        canopen = tuple(CanopenNode(name, spec.devices[name].node_id or 0, eds)
                        for name, eds in self.loaded.eds.items())
        node_ids = {f"{name} heartbeat": 0x700 + d.node_id
                    for name, d in spec.devices.items() if d.node_id is not None}
        periods = {s.quantity: m.period_s * 1000.0 for m in self.sent for s in m.sent
                   if m.period_s is not None}
        commands = tuple(r.quantity for m in self.received
                         if isinstance(m.spec, ReceivedMessage) and m.spec.command
                         for r in m.received)
        return Contract(rig=self.name, quantities=self.quantities, rows=1, binding_file=path,
                        default_binding_file=path, dut_node=spec.dut_node,
                        canopen_nodes=canopen, bitrate_bps=spec.bitrate_bps,
                        command_ids=self.command_ids(), node_ids=node_ids, periods_ms=periods,
                        dispersion_file=self.loaded.dispersion,
                        control_period_ms=spec.control_period_ms,
                        physics_period_ms=spec.fmu.step_ms, command_quantities=commands,
                        dut_node_id=spec.dut_node_id)


def truth_outputs(fmu: FmuDescription) -> list[VariableRef]:
    """Every floating-point output of the FMU, element by element: the run's truth."""
    out = []
    for variable in fmu.md.modelVariables:
        if variable.causality != "output" or variable.type not in ("Real", "Float64", "Float32"):
            continue
        size = fmu.ref(variable.name + ("[1]" if variable.dimensions else ""),
                       "truth", floating=True).size
        names = [variable.name] if not variable.dimensions else \
            [f"{variable.name}[{i}]" for i in range(1, size + 1)]
        out += [fmu.ref(n, "truth") for n in names]
    return out


def binding_path(plan: RigPlan) -> Path:
    """Where the rig's generated binding file is kept (a cache named by its content)."""
    text = binding_text(plan)
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    folder = Path(tempfile.gettempdir()) / "agrihil-ownrig"
    path = folder / f"{plan.name}-{digest}.binding.toml"
    if not path.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    return path


def binding_text(plan: RigPlan) -> str:
    """The binding as a binding file (TOML) says it."""
    def q(text: str) -> str:
        return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'

    lines = [f"# generated from {plan.loaded.path.name}: the rig's devices bound to its DBC",
             f"rig = {q(plan.name)}", f"database = {q(str(plan.loaded.dbc))}",
             f"dut_node = {q(plan.loaded.spec.dut_node)}", "", "[quantities]"]
    for name, carrier in plan.carriers.items():
        fields = ", ".join(f"{k} = {q(v) if isinstance(v, str) else repr(v)}"
                           for k, v in carrier.items())
        lines.append(f"{name} = {{ {fields} }}")
    return "\n".join(lines) + "\n"


def _signal(db: BusDatabase, message: str, signal: str, source: str, key: str) -> Any:
    msg = db.message(message)
    try:
        return msg.get_signal_by_name(signal)
    except KeyError:
        raise ConfigError(f"{message} has no signal {signal!r} (signals: "
                          f"{', '.join(s.name for s in msg.signals)})", path=source,
                          key=key) from None


def _unit(given: str, sig: Any, source: str, key: str) -> str:
    text = given or (sig.unit or "")
    try:
        unit = canonical(text)
    except ConfigError:
        raise ConfigError(f"unknown unit {text!r} (the {'rig file' if given else 'DBC'}'s; "
                          f"give unit = one of hil.contract.units)", path=source,
                          key=f"{key}.unit") from None
    if sig.unit and given:
        try:
            factor(unit, sig.unit)
        except ConfigError:
            raise ConfigError(f"{given!r} does not convert to the DBC's {sig.unit!r} of "
                              f"{sig.name}", path=source, key=f"{key}.unit") from None
    return unit


def _message(db: BusDatabase, name: str, source: str, key: str) -> Any:
    if not db.has_message(name):
        raise ConfigError(f"{db.path.name} has no message {name!r}", path=source, key=key)
    return db.message(name)


def build_plan(loaded: LoadedRigFile) -> RigPlan:
    """Check ``loaded`` against its FMU and DBC and resolve it.

    Raises
    ------
    ConfigError
        Naming the rig file and the key: an unknown message, signal, node, FMU variable,
        a variable of the wrong causality, a unit that does not convert, a name used twice.
    """
    spec, src = loaded.spec, loaded.source
    fmu = FmuDescription(loaded.fmu, src)
    fmu.parameter_refs(loaded.fmu_parameters, "fmu.parameters")
    try:
        db = BusDatabase(loaded.dbc)
    except (FrameError, ConfigError, OSError) as exc:
        raise ConfigError(f"cannot read the DBC: {exc}", path=src, key="dbc") from exc
    nodes = {n.name for n in db.db.nodes} if hasattr(db, "db") else set()
    if nodes and spec.dut_node not in nodes:
        raise ConfigError(f"{loaded.dbc.name} has no node {spec.dut_node!r} (nodes: "
                          f"{', '.join(sorted(nodes))})", path=src, key="dut_node")
    inputs: dict[str, tuple[str, VariableRef | None]] = {}
    for name, inp in spec.inputs.items():
        key = f"inputs.{name}"
        try:
            unit = canonical(inp.unit)
        except ConfigError:
            raise ConfigError(f"unknown unit {inp.unit!r}", path=src, key=f"{key}.unit") from None
        ref = fmu.ref(inp.fmu, f"{key}.fmu", causality=("input",)) if inp.fmu else None
        inputs[name] = (unit, ref)
    quantities: list[Quantity] = []
    carriers: dict[str, dict[str, Any]] = {}
    seen: dict[str, str] = {}
    sent: list[MessagePlan] = []
    received: list[MessagePlan] = []
    used_messages: dict[str, str] = {}

    def claim(quantity: str, key: str) -> None:
        if quantity in seen:
            raise ConfigError(f"quantity {quantity!r} is also {seen[quantity]}: give one of "
                              f"them another quantity = ...", path=src, key=key)
        seen[quantity] = key

    def claim_message(message: str, key: str) -> None:
        if message in used_messages:
            raise ConfigError(f"{message} is already played by {used_messages[message]}",
                              path=src, key=key)
        used_messages[message] = key

    for dname, device in spec.devices.items():
        dkey = f"devices.{dname}"
        if device.node and nodes and device.node not in nodes:
            raise ConfigError(f"{loaded.dbc.name} has no node {device.node!r} (nodes: "
                              f"{', '.join(sorted(nodes))})", path=src, key=f"{dkey}.node")
        for i, m in enumerate(device.send):
            mkey = f"{dkey}.send[{i}]"
            msg = _message(db, m.message, src, f"{mkey}.message")
            claim_message(m.message, f"{mkey}.message")
            if device.node and msg.senders and device.node not in msg.senders:
                raise ConfigError(f"{m.message} is sent by {', '.join(msg.senders)} in the "
                                  f"DBC, not by {device.node}", path=src, key=f"{mkey}.message")
            period_ms = m.period_ms if m.period_ms is not None else msg.cycle_time
            if not period_ms and not m.on_change:
                raise ConfigError(f"{m.message} has no cycle time in the DBC: give period_ms "
                                  f"or on_change = true", path=src, key=f"{mkey}.period_ms")
            plans = []
            for sname, s in m.signals.items():
                skey = f"{mkey}.signals.{sname}"
                sig = _signal(db, m.message, sname, src, skey)
                quantity = s.quantity or snake(f"{m.message}_{sname}")
                claim(quantity, skey)
                source = None
                if s.fmu:
                    source = fmu.ref(s.fmu, f"{skey}.fmu", causality=READABLE)
                    unit = _unit(s.unit or _fmu_unit(source), sig, src, skey)
                elif s.input:
                    if s.input not in inputs:
                        raise ConfigError(f"no input {s.input!r} (inputs: "
                                          f"{', '.join(inputs) or 'none'})", path=src,
                                          key=f"{skey}.input")
                    unit = _unit(s.unit or spec.inputs[s.input].unit, sig, src, skey)
                else:
                    unit = _unit(s.unit, sig, src, skey) if (s.unit or sig.unit) else ""
                kind = "counter" if s.counter else "number"
                quantities.append(_quantity(quantity, unit, "to_dut", sig, kind,
                                            f"{dname}: {m.message}.{sname}"))
                carriers[quantity] = {"message": m.message, "signal": sname,
                                      **({"unit": unit} if unit and not sig.unit else {})}
                plans.append(SentPlan(quantity, sname, s, unit, source, skey))
            sent.append(MessagePlan(dname, m.message, msg.frame_id,
                                    period_ms / 1000.0 if period_ms else None, m,
                                    sent=tuple(plans)))
        for i, r in enumerate(device.receive):
            mkey = f"{dkey}.receive[{i}]"
            msg = _message(db, r.message, src, f"{mkey}.message")
            claim_message(r.message, f"{mkey}.message")
            if msg.senders and spec.dut_node not in msg.senders:
                raise ConfigError(f"{r.message} is sent by {', '.join(msg.senders)} in the "
                                  f"DBC, not by the controller ({spec.dut_node})", path=src,
                                  key=f"{mkey}.message")
            rplans = []
            for sname, s in r.signals.items():
                skey = f"{mkey}.signals.{sname}"
                sig = _signal(db, r.message, sname, src, skey)
                quantity = s.quantity or snake(f"{r.message}_{sname}")
                claim(quantity, skey)
                target = fmu.ref(s.fmu, f"{skey}.fmu", causality=("input",))
                unit = _unit(s.unit, sig, src, skey) if (s.unit or sig.unit) else ""
                quantities.append(_quantity(quantity, unit, "from_dut", sig, "number",
                                            f"{dname}: {r.message}.{sname}"))
                carriers[quantity] = {"message": r.message, "signal": sname,
                                      **({"unit": unit} if unit and not sig.unit else {})}
                rplans.append(ReceivedPlan(quantity, sname, s, unit, target, skey))
            received.append(MessagePlan(dname, r.message, msg.frame_id, None, r,
                                        received=tuple(rplans)))
    if not any(isinstance(m.spec, ReceivedMessage) and m.spec.command for m in received):
        raise ConfigError("no device receives a command from the controller (a received "
                          "message with command = true): lockstep has nothing to wait for",
                          path=src, key="devices")
    to_dut = {q.name: q for q in quantities if q.direction == "to_dut"}
    controlled = {}
    for cname, c in spec.controlled.items():
        ckey = f"controlled.{cname}"
        if c.target not in inputs:
            raise ConfigError(f"no input {c.target!r} (inputs: {', '.join(inputs) or 'none'})",
                              path=src, key=f"{ckey}.target")
        if c.sensed not in to_dut:
            raise ConfigError(f"no quantity {c.sensed!r} sent by a device (sent: "
                              f"{', '.join(to_dut)})", path=src, key=f"{ckey}.sensed")
        truth = fmu.ref(c.truth, f"{ckey}.truth", causality=("output",))
        try:
            unit = canonical(c.unit)
        except ConfigError:
            raise ConfigError(f"unknown unit {c.unit!r}", path=src, key=f"{ckey}.unit") from None
        for what, other in (("sensed", to_dut[c.sensed].unit), ("target", inputs[c.target][0]),
                            ("truth", _fmu_unit(truth))):
            if other and canonical(other) != unit:
                raise ConfigError(f"the {what} is in {other!r}, the controlled quantity in "
                                  f"{unit!r}: they must be one unit", path=src,
                                  key=f"{ckey}.unit")
        controlled[cname] = ControlledPlan(cname, c.target, c.sensed, truth, unit, c.band, c)
    return RigPlan(loaded, fmu, db, sent, received, inputs, controlled, tuple(quantities),
                   carriers)


def _fmu_unit(ref: VariableRef) -> str:
    try:
        return canonical(ref.unit) if ref.unit else ""
    except ConfigError:
        return ""


def _quantity(name: str, unit: str, direction: Any, sig: Any, kind: Any,
              what: str) -> Quantity:
    scale = abs(float(sig.scale or 1.0))
    low = float(sig.minimum) if sig.minimum is not None else -1e12
    high = float(sig.maximum) if sig.maximum is not None else 1e12
    if kind == "counter":
        low, high = 0.0, float((1 << sig.length) - 1)
    if sig.unit and unit:
        try:
            f = factor(sig.unit, unit)
            low, high, scale = [*sorted((low * f, high * f)), scale * abs(f)]
        except ConfigError:
            pass
    return Quantity(name, unit, direction, low, high, scale, what, kind=kind)
