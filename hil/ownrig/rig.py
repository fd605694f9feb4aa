"""A rig file as a :class:`~hil.rig.Rig`: the FMU is the physics, the devices its CAN nodes.

:func:`rig_class` makes one :class:`OwnRig` subclass per rig file (its name, periods, inputs,
faults and plot panels are class attributes, as a built-in rig's are), so the one loop
(:func:`hil.rig.run_scenario`), the suites, campaigns and the gate run it as they run the
built-in rigs. A profile's ``[rig]`` table (or a campaign's dispersion) overrides the rig
file's keys, ``fmu.parameters`` included.

Faults every rig of your own has: ``<device>_silent`` (the device sends nothing),
``<device>_frozen`` (it repeats its last frames: a sensor stuck) and ``controller_silent`` (no
frame of the controller reaches the rig: a cut wire).
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping
from dataclasses import asdict, make_dataclass
from functools import cache
from pathlib import Path
from typing import Any, ClassVar

import can
import numpy as np

from hil.contract.codec import ContractCodec
from hil.contract.quantity import Contract
from hil.errors import ConfigError
from hil.ownrig.config import LoadedRigFile, load_rig_file
from hil.ownrig.devices import ActuatorDevice, NmtNode, SenderDevice
from hil.ownrig.fmu import FmuPlant
from hil.ownrig.plan import RigPlan, build_plan
from hil.ownrig.sensor import SensorModel
from hil.rig.base import Rig, RigContext
from hil.rig.scenario import Scenario


def trace_name(prefix: str, text: str) -> str:
    """A trace's name: ``prefix`` and ``text`` in letters, digits and ``_`` (``y[1]`` → ``y_1``)."""
    return f"{prefix}_{re.sub(r'[^A-Za-z0-9_]+', '_', text).strip('_')}"


def config_view(plan: RigPlan) -> object:
    """The rig's config as campaigns see it: a frozen dataclass with ``parameters`` (the rig
    file's named parameters) and ``fmu.parameters`` (the FMU's scalar real parameters), so a
    dispersion file names them ``parameters.motor_gain`` or ``fmu.parameters.K``; and the rig
    file's hash (every key, for the record)."""
    spec = plan.loaded.spec
    own = make_dataclass("RigParameters", [(k, float) for k in spec.parameters], frozen=True)
    scalars = {k: v for k, v in plan.loaded.fmu_parameters.items()
               if isinstance(v, float) and k.isidentifier()}
    fmu_params = make_dataclass("FmuParameters", [(k, float) for k in scalars], frozen=True)
    fmu = make_dataclass("FmuConfig", [("path", str), ("step_ms", float),
                                       ("parameters", fmu_params)], frozen=True)
    view = make_dataclass("OwnRigConfig", [("name", str), ("parameters", own), ("fmu", fmu),
                                           ("rig_file_sha256", str)], frozen=True)
    text = json.dumps(asdict(spec), sort_keys=True, default=str)
    return view(spec.name, own(**spec.parameters),
                fmu(str(plan.loaded.fmu), spec.fmu.step_ms, fmu_params(**scalars)),
                hashlib.sha256(text.encode()).hexdigest())


def truth_units(plan: RigPlan) -> dict[str, str]:
    """Each FMU scalar's unit: the FMU's own, else the controlled quantity's or the sensed
    signal's it feeds (the rig file's word for a model that declares none)."""
    units: dict[str, str] = {}
    for ref in plan.watched():
        if ref.unit:
            units[ref.text] = ref.unit
    for c in plan.controlled.values():
        units.setdefault(c.truth.text, c.unit)
    for message in plan.sent:
        for s in message.sent:
            if s.source is not None and s.unit and s.spec.gain == 1.0 and s.spec.offset == 0.0:
                units.setdefault(s.source.text, s.unit)
    return units


@cache
def _plan(path: str, overrides_json: str, source: str) -> RigPlan:
    overrides = json.loads(overrides_json)
    return build_plan(load_rig_file(path, overrides or None, source=source))


def plan_for(path: Path, overrides: Mapping[str, Any] | None = None,
             source: str = "") -> RigPlan:
    """The rig file's plan with ``overrides`` applied (read and checked once per process)."""
    return _plan(str(path), json.dumps(dict(overrides or {}), sort_keys=True), source)


def _spawn(rng: np.random.Generator) -> np.random.Generator:
    return rng.spawn(1)[0]


class OwnRig(Rig):
    """A rig of your own; :func:`rig_class` makes one subclass per rig file."""

    rig_file: ClassVar[Path]
    loaded: ClassVar[LoadedRigFile]
    await_any_command = False

    @classmethod
    def plan(cls, overrides: Mapping[str, Any] | None = None, source: str = "") -> RigPlan:
        return plan_for(cls.rig_file, overrides, source)

    @classmethod
    def load_config(cls, overrides: Mapping[str, Any] | None = None, *,
                    source: str = "") -> object:
        """The rig file's dispersable parameters as a config object (see :func:`config_view`),
        with ``overrides`` (a profile's ``[rig]``, a campaign sample's draws) applied."""
        return config_view(cls.plan(overrides, source))

    @classmethod
    def bus_contract(cls, overrides: Mapping[str, Any] | None = None,
                     source: str = "") -> Contract:
        """The rig's bus contract (quantities, generated binding, nodes, periods)."""
        return cls.plan(overrides, source).contract()

    def __init__(self, ctx: RigContext) -> None:
        super().__init__(ctx)
        plan = self.plan(ctx.config_overrides, ctx.config_source)
        self.plan_ = plan
        spec = plan.loaded.spec
        self.codec = ContractCodec(plan.contract(), plan.binding(), plan.database)
        self.plant = FmuPlant(plan.fmu, plan.loaded.fmu_parameters, self.physics_period_s,
                              plan.watched())
        self.input_values = {name: inp.initial for name, inp in spec.inputs.items()}
        for name, (_, ref) in plan.inputs.items():
            if ref is not None:
                self.plant.set(ref, self.input_values[name])
        self.controller_silent = False
        self.sensors: dict[str, SensorModel] = {}
        for message in plan.sent:     # fixed order: each sensor's stream from the run's
            for s in message.sent:
                if s.source is not None:
                    self.sensors[s.quantity] = SensorModel(s.spec, _spawn(ctx.rng))
        self._history = [(s, self.plant.slot(ref.text)) for q, s in self.sensors.items()
                         for m in plan.sent for x in m.sent if x.quantity == q
                         for ref in (x.source,) if ref is not None and s.needs_history]
        self._every_step = any(s.needs_every_step for s, _ in self._history)
        self.nodes: dict[str, Any] = {}
        for name, device in spec.devices.items():
            if name in plan.loaded.eds:
                from hil.rig.canopen_device import CanopenDevice
                self.nodes[name] = CanopenDevice(name, device.node_id or 0,
                                                 plan.loaded.eds[name])
            elif device.node_id is not None:
                self.nodes[name] = NmtNode(name, device.node_id, device.heartbeat_ms / 1000.0,
                                           ctx.note)
        self.senders = [SenderDevice(m, self.codec, self.plant, self.sensors,
                                     self.input_values.__getitem__, self.physics_period_s,
                                     self._gate(m.device)) for m in plan.sent]
        self.actuators = [ActuatorDevice(m, self.codec, self.plant, ctx.note,
                                         self._gate(m.device)) for m in plan.received]
        self.devices = [*self.senders, *self.actuators, *self.nodes.values()]
        units = truth_units(plan)
        self._truth = [(trace_name("true", ref.text), units.get(ref.text, "1"),
                        self.plant.slot(ref.text)) for ref in plan.watched()
                       if ref.causality == "output"]
        self._sensed = [(trace_name("sensed", s.quantity), s.unit or "1", sender, s.quantity)
                        for sender in self.senders for s in sender.plan.sent]
        self._commanded = [(trace_name("cmd", r.quantity), r.unit or "1", act, r.quantity)
                           for act in self.actuators for r in act.plan.received]
        self._inputs = [(name, unit) for name, (unit, _) in plan.inputs.items()]
        if self._history:
            values = self.plant.values()
            for sensor, slot in self._history:
                sensor.record(0.0, values[slot])

    def _gate(self, device: str) -> Any:
        node = self.nodes.get(device)
        return (lambda: bool(node.operational)) if node is not None else None

    # --- physics ---------------------------------------------------------------------------
    def advance(self, n: int, dt: float) -> None:
        if not self._history:
            self.plant.advance(n, dt)
            return
        if not self._every_step:      # windows only: their past at the rig's event times
            self.plant.advance(n, dt)
            values = self.plant.values()
            t = self.plant.time_s
            for sensor, slot in self._history:
                sensor.record(t, values[slot])
            return
        for _ in range(n):
            self.plant.advance(1, dt)
            values = self.plant.values()
            t = self.plant.time_s
            for sensor, slot in self._history:
                sensor.record(t, values[slot])

    def physics_engines(self) -> dict[str, str]:
        fmu = self.plan_.fmu
        return {"plant": f"FMU {fmu.path.name} (FMI {fmu.fmi_version} co-simulation, fmpy)"}

    # --- scenario --------------------------------------------------------------------------
    def set_input(self, name: str, value: float, time_s: float) -> None:
        if name == "ground_speed_mps" and name not in self.input_values:
            return    # the runner's speed profile: only for rigs that declare the input
        if name not in self.input_values:
            raise ConfigError(f"unknown input {name!r}", key=name)
        self.input_values[name] = value
        ref = self.plan_.inputs[name][1]
        if ref is not None:
            self.plant.set(ref, value)

    def set_fault(self, name: str, active: bool, target: int | None, time_s: float) -> None:
        if name == "controller_silent":
            self.controller_silent = active
            return
        for suffix in ("_silent", "_frozen"):
            device = name.removesuffix(suffix)
            if name.endswith(suffix) and device in self.plan_.loaded.spec.devices:
                for d in self.devices:
                    if getattr(d, "device", None) == device or d is self.nodes.get(device):
                        if suffix == "_silent":
                            d.silent = active
                        elif isinstance(d, SenderDevice):
                            d.frozen = active
                return
        raise ConfigError(f"unknown fault {name!r}", key=name)

    def command_ids(self) -> frozenset[int]:
        return self.plan_.command_ids()

    def admits(self, msg: can.Message) -> bool:
        return not self.controller_silent

    # --- records ---------------------------------------------------------------------------
    def trace_signals(self) -> dict[str, tuple[float, str]]:
        values = self.plant.values()
        out: dict[str, tuple[float, str]] = {}
        for name, unit in self._inputs:
            out[name] = (self.input_values[name], unit or "1")
        for name, unit, slot in self._truth:
            out[name] = (values[slot], unit)
        for name, unit, sender, quantity in self._sensed:
            out[name] = (sender.sensed[quantity], unit)
        for name, unit, act, quantity in self._commanded:
            out[name] = (act.commanded[quantity], unit)
        return out

    def truth(self) -> dict[str, object]:
        values = self.plant.values()
        return {name: values[slot] for name, _, slot in self._truth}

    def close(self) -> None:
        self.plant.close()

    @classmethod
    def scenario_dir(cls) -> Path:
        if cls.loaded.scenarios is None:
            raise NotImplementedError
        return cls.loaded.scenarios

    @classmethod
    def scenario_names(cls) -> list[tuple[str, str]]:
        if cls.loaded.scenarios is None:
            return []
        return super().scenario_names()

    @classmethod
    def load_scenario(cls, name_or_path: str) -> Scenario:
        if not Path(name_or_path).suffix and cls.loaded.scenarios is None:
            raise ConfigError(f"the rig file {cls.rig_file.name} names no scenarios "
                              f"directory: give a scenario file", key="scenario")
        return super().load_scenario(name_or_path)


@cache
def _rig_class(path: str) -> type[OwnRig]:
    plan = plan_for(Path(path))
    spec = plan.loaded.spec
    from hil.ownrig.check import validate_fmu_file

    validate_fmu_file(plan.fmu.path, plan.loaded.source)
    from hil.ownrig.measurements import register

    register(plan)
    devices_sending = sorted({m.device for m in plan.sent})
    faults = {"controller_silent": "no frame of the controller reaches the rig (cut wire)",
              **{f"{d}_silent": f"the {d} device sends nothing" for d in spec.devices},
              **{f"{d}_frozen": f"the {d} device repeats its last frames (a frozen sensor)"
                 for d in devices_sending}}
    inputs = {name: (inp.description or f"scenario input, {inp.unit}")
              for name, inp in spec.inputs.items()}
    groups = [(f"{name} [{c.unit}]", [c.target, trace_name("sensed", c.sensed),
                                      trace_name("true", c.truth.text)])
              for name, c in plan.controlled.items()]
    groups += [("commands", [trace_name("cmd", r.quantity) for m in plan.received
                             for r in m.received])]
    attrs = {"name": spec.name, "rig_file": Path(path), "loaded": plan.loaded,
             "physics_period_s": spec.fmu.step_ms / 1000.0,
             "control_period_s": spec.control_period_ms / 1000.0,
             "trace_period_s": spec.trace_period_ms / 1000.0,
             "bitrate_bps": spec.bitrate_bps, "inputs": inputs, "faults": faults,
             "plot_groups": groups, "__doc__": spec.description or f"rig file {path}"}
    return type(f"OwnRig_{spec.name}", (OwnRig,), attrs)


def rig_class(path: str | Path) -> type[OwnRig]:
    """The rig class of a rig file (checked against its FMU and DBC; one class per file).

    Raises
    ------
    ConfigError
        The rig file, its FMU or its DBC is refused (naming the file and the key).
    """
    return _rig_class(str(Path(path).resolve()))

