"""The fertilizer-flow rig of [F]: physics, its CAN nodes, scenarios and truth."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from itertools import chain
from pathlib import Path
from typing import Any, ClassVar

import can

from hil.contract.binding import load_binding
from hil.contract.codec import ContractCodec
from hil.contract.quantity import Contract
from hil.errors import ConfigError
from hil.rig import Rig, RigContext
from hil.rig.device import Heartbeat
from plant_emulators.fertilizer.analog_output import AnalogOutputChannel
from plant_emulators.fertilizer.calibration_test import (
    CalibrationTest,
    lot_seed_words,
    run_calibration_test,
)
from plant_emulators.fertilizer.config import FertilizerRigConfig, load_rig_config
from plant_emulators.fertilizer.devices import (
    AnalogOutputModule,
    CalibrationDevice,
    FlowModuleDevice,
    GroundWheelDevice,
    TerminalDevice,
    TractorSpeedDevice,
)
from plant_emulators.fertilizer.field_run import FIELD_FAULTS, BoomGeometry, FieldRun
from plant_emulators.fertilizer.flow_sensor import REPORT_FAULTS, FlowSensor
from plant_emulators.fertilizer.frames import FertilizerDatabase, bus_contract
from plant_emulators.fertilizer.ground_speed import GroundSpeedModel
from plant_emulators.fertilizer.physics import FertilizerPlant

MODE_FIELD, MODE_BENCH, MODE_CONSTANT = 0, 1, 2


def _switches_rows(scenario: Any) -> bool:
    """The scenario sets the terminal's ``active_rows`` (initially or by an event)."""
    return "active_rows" in scenario.initial or any(
        "active_rows" in (event.set or {}) for event in scenario.events)


class FertilizerRig(Rig):
    name = "fertilizer"
    physics_period_s = 0.001
    control_period_s = 0.1
    trace_period_s = 0.01
    inputs: ClassVar[dict[str, str]] = {
        "terminal_mode": "0 field rate, 1 bench flow, 2 constant speed (FertSetpoint.Mode)",
        "enable": "0/1: the terminal enables metering",
        "target_flow_gps": "bench target flow per row, g/s",
        "rate_kg_per_hm2": "field target rate M, kg/hm2",
        "width_m": "field working width D, m",
        "ground_speed_mps": "tractor ground speed the driver holds, m/s",
        "speed_source": "0 Hall wheel, 1 PGN 65096, 2 PGN 65097 (FertSetpoint.SpeedSource)",
        "active_rows": "rows 1..N metering (FertSetpoint.ActiveRows, N rows share the total "
                       "target): their clutches in, the others' out",
        "lot_offset_frac": "at 0 s only: the run's fertilizer lot delivers this fraction more "
                           "than the lot the controllers' own calibration was made on "
                           "(calibration_test.calibrated_lot_frac)",
        "calibration_test": "at 0 s only: 1 the operator ran the calibration test of the lot "
                            "(the terminal sends MeterCalibration), 0 not; by default it did "
                            "whenever the lot is not the calibrated one",
    }
    faults: ClassVar[dict[str, str]] = {
        "flow_sensor_silent": "the flow module of row <target> sends nothing",
        "flow_sensor_stale": "the flow module of row <target> repeats its last report",
        "flow_sensor_garbage": "the flow module of row <target> reports garbage",
        **{f"flow_sensor_{kind}": f"the flow module of row <target>: {what}"
           for kind, what in REPORT_FAULTS.items()},
        "motor_stall": "the meter shaft jams",
        "controller_silent": "no frame of the controller reaches the rig (cut wire)",
        **{name: f"field runs under a TC ([tractor] scenarios): {what}"
           for name, what in FIELD_FAULTS.items()},
    }
    plot_groups: ClassVar[list[tuple[str, list[str]]]] = [
        ("flow, row 1 [g/s]", ["target_flow_row_gps", "sensed_flow_1_gps",
                               "flow_at_sensor_1_gps"]),
        ("delivered (truth) [g]", ["delivered_total_g", "target_mass_total_g"]),
        ("motor", ["command_v", "shaft_speed_rpm"]),
        ("ground speed [m/s]", ["ground_speed_mps", "wheel_speed_mps"]),
    ]

    @classmethod
    def load_config(cls, overrides: Mapping[str, Any] | None = None, *,
                    source: str = "") -> FertilizerRigConfig:
        return load_rig_config(overrides=overrides, source=source)

    @classmethod
    def bus_contract(cls, overrides: Mapping[str, Any] | None = None,
                     source: str = "") -> Contract:
        """The rig's bus contract (quantities, binding in force, nodes) under ``overrides``."""
        return bus_contract(load_rig_config(overrides=overrides, source=source))

    @staticmethod
    def contract_codec(config: FertilizerRigConfig) -> ContractCodec:
        """The codec of the binding in force under ``config``.

        The rig's own DBC is first checked against the wiring (its ids follow the node ids);
        a DUT's database is bound as it is (``hil profile check`` judges it).
        """
        contract = bus_contract(config)
        binding = load_binding(contract.binding_file)
        if binding.database == Path(config.wiring.dbc_file):
            return ContractCodec(contract, binding, FertilizerDatabase.from_config(config))
        return ContractCodec(contract, binding)

    def __init__(self, ctx: RigContext, config: FertilizerRigConfig | None = None) -> None:
        super().__init__(ctx)
        cfg = config or load_rig_config(overrides=ctx.config_overrides,
                                        source=ctx.config_source)
        self.config = cfg
        self.codec = self.contract_codec(cfg)
        wiring = cfg.wiring
        rows = cfg.meter.rows
        self.rows = rows
        # fixed construction order: each model spawns its own stream from the run's generator
        self.plant = FertilizerPlant(cfg, ctx.rng)
        self.sensors = [FlowSensor(cfg.flow_sensor, ctx.rng) for _ in range(rows)]
        self.speed = GroundSpeedModel(cfg.ground_speed, ctx.rng)
        self.analog = AnalogOutputModule(wiring.analog_output_node_id,
                                         str(wiring.analog_output_eds_file),
                                         AnalogOutputChannel(cfg.analog_output, ctx.rng),
                                         wiring.analog_output_channel)
        valid_max = self.codec.contract.quantity("row_flow").maximum
        self.flow_modules = [FlowModuleDevice(row + 1, sensor, self.codec, valid_max)
                             for row, sensor in enumerate(self.sensors)]
        self.terminal = TerminalDevice(self.codec, wiring.setpoint_period_ms / 1000.0, rows)
        #: the run's lot (density_offset_mean_frac, or what the scenario sets at 0 s), whether
        #: the operator tested it (None: whenever it is not the calibrated lot) and the test
        self.lot_frac = cfg.fertilizer.density_offset_mean_frac
        self._lot_set_by_scenario = False
        self._calibration_performed: bool | None = None
        self._calibration: CalibrationTest | None = None
        self.calibration = CalibrationDevice(
            self.codec, cfg.calibration_test.frame_period_ms / 1000.0, self.calibration_test)
        tractor = ctx.scenario.tractor if ctx.scenario is not None else None
        #: a field run under a Task Controller: the rig is an ISOBUS tractor (field_run.py);
        #: its TECU and TC replace the terminal's FertSetpoint and the speed frames
        self.field_run = (FieldRun(tractor, BoomGeometry(cfg.boom.width_m, rows,
                                                         cfg.boom.opener_offset_m))
                          if tractor is not None else None)
        tractor_side = ([self.field_run.device] if self.field_run is not None else
                        [TractorSpeedDevice(self.speed, self.codec,
                                            wiring.tractor_speed_period_ms / 1000.0),
                         self.terminal, self.calibration])
        self.devices = [
            *self.flow_modules,
            GroundWheelDevice(self.speed, self.codec, wiring.ground_speed_period_ms / 1000.0),
            *tractor_side,
            self.analog,
            *(Heartbeat(f"flow module {i + 1}", node) for i, node in
              enumerate(wiring.flow_module_node_ids)),
            Heartbeat("ground wheel speed", wiring.ground_speed_node_id),
        ]
        self.dut_node_id = wiring.dut_node_id
        self._command_ids = self.command_ids()
        self.controller_silent = False
        self.time_s = 0.0
        self.target_mass_g = 0.0          # per row, integral of the target flow while enabled
        #: switched rows (the terminal's ActiveRows, rows 1..N metering): each row's own
        #: target mass and its clutch traced, for scenarios that switch rows (``active_rows``)
        self.active_rows = rows
        self.target_mass_row_g = [0.0] * rows
        self.switched_rows = ctx.scenario is not None and _switches_rows(ctx.scenario)
        self.dut_heartbeat_lost = False
        self.dut_status: dict[str, float] = {}
        self._passed = list(self.plant.sensor_passed_g)
        #: (name, unit) of every traced signal, in :meth:`trace_row` order
        self._trace_layout: tuple[tuple[str, str], ...] = (
            ("target_flow_row_gps", "g/s"), ("command_v", "V"), ("motor_speed_rpm", "rpm"),
            ("shaft_speed_rpm", "r/min"), ("motor_current_a", "A"),
            ("ground_speed_mps", "m/s"), ("wheel_speed_mps", "m/s"),
            ("analog_comm_error", "1"), ("delivered_total_g", "g"),
            ("target_mass_total_g", "g"),
            *((f"{name}_{row + 1}_{unit_name}", unit) for row in range(rows)
              for name, unit_name, unit in (("flow_at_meter", "gps", "g/s"),
                                            ("flow_at_sensor", "gps", "g/s"),
                                            ("sensed_flow", "gps", "g/s"),
                                            ("delivered", "g", "g"))),
            *((("east_m", "m"), ("north_m", "m"), ("heading_deg", "deg"),
               ("prescribed_rate_kg_ha", "kg/ha"),
               *((f"clutch_{row + 1}", "1") for row in range(rows)))
              if self.field_run is not None else ()),
            *((f"clutch_{row + 1}", "1") for row in range(rows) if self.switched_rows))
        self._pose = self.field_run.pose(0.0) if self.field_run is not None else None
        #: the map's rate under the openers at ``_pose`` (kg/ha)
        self._rate_now = (self.field_run.prescribed_rate(self._pose)
                          if self.field_run is not None and self._pose is not None else 0.0)

    # --- physics ---------------------------------------------------------------------------
    def target_flow_row_gps(self) -> float:
        """The flow per row the operator asked for, by the truth: field targets follow the
        true ground speed (eq. 1, Q = 0.1·M·D·v), bench targets are set directly."""
        if self.field_run is not None:
            # the map's rate under the openers over a row's strip at the path's speed, on the
            # passes (0.1·M·(D/rows)·v); sections and coverage are the suite's to judge
            pose = self._pose
            if pose is None or pose.kind not in ("pass", "overlap"):
                return 0.0
            return 0.1 * self._rate_now * self.field_run.geometry.row_width_m * pose.speed_m_s
        if not self.terminal.enable:
            return 0.0
        if self.terminal.mode == MODE_FIELD:
            t = self.terminal
            return (0.1 * t.rate_kg_per_hm2 * t.width_m * self.speed.true_speed_mps
                    / self.active_rows)
        return self.terminal.target_flow_gps

    def advance(self, n: int, dt: float) -> None:
        if self.field_run is not None:
            self._follow_the_path()
        self.analog.update(self.time_s)
        self.plant.command_v = self.analog.output_volts()
        target = self.target_flow_row_gps()
        self.speed.advance(n, dt)
        self.plant.advance(n, dt)
        span = n * dt
        passed = self.plant.sensor_passed_g
        vibration = self.speed.vibration_rms_mps2
        for sensor, now, before in zip(self.sensors, passed, self._passed, strict=True):
            sensor.vibration_rms_mps2 = vibration
            sensor.advance(n, dt, (now - before) / span)
        self._passed = passed
        if self.active_rows == self.rows:
            self.target_mass_g += target * span
        else:       # the mean over rows of the rows' targets: the off rows' is 0
            self.target_mass_g += target * span * self.active_rows / self.rows
        if self.switched_rows:
            for row in range(self.active_rows):
                self.target_mass_row_g[row] += target * span
        self.time_s += span

    def _follow_the_path(self) -> None:
        """Field run: the tractor where the path says, the rows' clutches as the DUT last
        reported its sections."""
        run = self.field_run
        assert run is not None
        self._pose = run.pose(self.time_s)
        self._rate_now = run.prescribed_rate(self._pose)
        self.speed.target_speed_mps = self._pose.speed_m_s
        self.plant.engage_rows(run.update_clutches(self.time_s))
        while run.notes:
            self.ctx.note(*run.notes.pop(0))

    def calibration_test(self) -> CalibrationTest | None:
        """The operator's calibration test of the run's lot, or None when none was made (the
        lot is the one the controllers' own calibration was made on, or the scenario says
        so). The test of a campaign sample's lot is the same in all its runs: its draws are
        seeded by the lot; a lot the scenario sets is tested with the run's seed."""
        performed = self._calibration_performed
        if performed is None:
            performed = self.lot_frac != self.config.calibration_test.calibrated_lot_frac
        if not performed:
            return None
        if self._calibration is None:
            words = lot_seed_words(self.lot_frac)
            if self._lot_set_by_scenario:
                words = (self.ctx.seed & 0xFFFFFFFF, *words)
            self._calibration = run_calibration_test(self.config, self.lot_frac,
                                                     seed_words=words)
        return self._calibration

    def _set_lot(self, name: str, value: float, time_s: float) -> None:
        if time_s > 0.0:
            raise ConfigError(f"{name} is the run's lot and the operator's test before it: set "
                              f"it in [initial] (0 s), not at {time_s:g} s", key=name)
        if name == "calibration_test":
            if value not in (0.0, 1.0):
                raise ConfigError(f"calibration_test must be 0 or 1, got {value}", key=name)
            self._calibration_performed = bool(value)
            return
        if not -0.5 < value < 0.5:
            raise ConfigError(f"lot_offset_frac must be within +-0.5, got {value}", key=name)
        lot = self.config.calibration_test.calibrated_lot_frac + value
        self.plant.density_offset_frac += lot - self.lot_frac
        self.lot_frac = lot
        self._lot_set_by_scenario = True
        self._calibration = None

    def physics_engines(self) -> dict[str, str]:
        return {"plant": self.plant.engine, "ground_speed": self.speed.engine,
                "flow_sensors": self.sensors[0].engine}

    # --- scenario --------------------------------------------------------------------------
    def set_input(self, name: str, value: float, time_s: float) -> None:
        t = self.terminal
        if name == "ground_speed_mps":     # first: the runner sets it every trace period
            self.speed.target_speed_mps = value
        elif name == "terminal_mode":
            if value not in (MODE_FIELD, MODE_BENCH, MODE_CONSTANT):
                raise ConfigError(f"terminal_mode must be 0, 1 or 2, got {value}", key=name)
            t.mode = int(value)
        elif name == "enable":
            t.enable = bool(value)
        elif name == "target_flow_gps":
            t.target_flow_gps = value
        elif name == "rate_kg_per_hm2":
            t.rate_kg_per_hm2 = value
        elif name == "width_m":
            t.width_m = value
        elif name == "speed_source":
            t.speed_source = int(value)
        elif name == "active_rows":
            self._switch_rows(value)
        elif name in ("lot_offset_frac", "calibration_test"):
            self._set_lot(name, value, time_s)
        else:
            raise ConfigError(f"unknown input {name!r}", key=name)

    def _switch_rows(self, value: float) -> None:
        """The terminal's ActiveRows = N: rows 1..N metering (their clutches in), the others'
        clutches out; the terminal sends N in FertSetpoint from its next frame on."""
        if self.field_run is not None:
            raise ConfigError("active_rows is the terminal's: a field run under a Task "
                              "Controller switches rows by its sections", key="active_rows")
        if value != int(value) or not 1 <= value <= self.rows:
            raise ConfigError(f"active_rows must be a whole number of rows 1..{self.rows}, "
                              f"got {value}", key="active_rows")
        self.active_rows = int(value)
        self.terminal.rows = self.active_rows
        self.plant.engage_rows(tuple(row < self.active_rows for row in range(self.rows)))

    def set_fault(self, name: str, active: bool, target: int | None, time_s: float) -> None:
        if name.startswith("flow_sensor_"):
            if target is None or not 1 <= target <= self.rows:
                raise ConfigError(f"{name} needs a target row 1..{self.rows}, got {target}",
                                  key="target")
            module = self.flow_modules[target - 1]
            if name == "flow_sensor_silent":
                module.silent = active
            elif name == "flow_sensor_stale":
                module.stale = active
            elif name == "flow_sensor_garbage":
                module.sensor.garbage = active
            elif name.removeprefix("flow_sensor_") in REPORT_FAULTS:
                module.sensor.set_report_fault(
                    name.removeprefix("flow_sensor_") if active else None, time_s)
            else:
                raise ConfigError(f"unknown fault {name!r}", key=name)
        elif name == "motor_stall":
            self.plant.stalled = active
        elif name == "controller_silent":
            self.controller_silent = active
        elif name in FIELD_FAULTS:
            if self.field_run is None:
                raise ConfigError(f"{name} needs a field run under a Task Controller (a "
                                  f"scenario with a [tractor] table)", key=name)
            self.field_run.set_fault(name, active, time_s)
        else:
            raise ConfigError(f"unknown fault {name!r}", key=name)

    # --- frames from the controller ---------------------------------------------------------
    def command_ids(self) -> frozenset[int]:
        return frozenset({self.codec.frame_id("motor_command")})

    def admits(self, msg: can.Message) -> bool:
        return not self.controller_silent

    def on_dut_frame(self, msg: can.Message, time_s: float) -> None:
        if msg.arbitration_id in self._command_ids:
            return
        values = self.codec.decode(msg)
        if values and "dut_target_flow" in values:
            self.dut_status = {k: float(v) for k, v in values.items()}

    def watch(self, time_s: float) -> None:
        """Note when the controller's heartbeat (consumed by the analog module) stops and
        when it comes back."""
        last = self.analog.last_watched_heartbeat_s
        timeout = self.analog.consumer_time_s or 1.0
        lost = last > -math.inf and time_s - last > timeout
        if lost != self.dut_heartbeat_lost:
            self.dut_heartbeat_lost = lost
            self.ctx.note(time_s, "dut-heartbeat",
                          "controller heartbeat lost" if lost else "controller heartbeat back")

    # --- records -------------------------------------------------------------------------------
    def trace_signals(self) -> dict[str, tuple[float, str]]:
        return {name: (value, unit) for (name, unit), value in
                zip(self._trace_layout, self.trace_row(), strict=True)}

    def trace_row(self) -> tuple[float, ...]:
        """The traced values in :attr:`_trace_layout` order (what :meth:`trace_signals`
        pairs with the names and units)."""
        self.watch(self.time_s)
        p = self.plant
        delivered = p.delivered_g
        return (self.target_flow_row_gps(), p.command_v, p.motor_speed_rpm, p.shaft_speed_rpm,
                p.motor_current_a, self.speed.true_speed_mps,
                self.speed.hall_report().wheel_speed_mps, float(self.analog.comm_error),
                sum(delivered), self.target_mass_g * self.rows,
                *chain.from_iterable(zip(p.flow_at_meter_gps, p.flow_at_sensor_gps,
                                         [m.reported_flow_gps for m in self.flow_modules],
                                         delivered, strict=True)),
                *(self._field_row() if self.field_run is not None else ()),
                *((1.0 if c else 0.0 for c in p.row_engaged) if self.switched_rows else ()))

    def _field_row(self) -> tuple[float, ...]:
        pose = self._pose
        run = self.field_run
        assert pose is not None and run is not None
        return (pose.east_m, pose.north_m, pose.heading_deg, self._rate_now,
                *(1.0 if c else 0.0 for c in self.plant.row_engaged))

    def truth(self) -> dict[str, object]:
        p = self.plant
        return {"delivered_g": list(p.delivered_g), "in_transit_g": list(p.in_transit_g),
                "delivered_total_g": sum(p.delivered_g),
                "target_mass_per_row_g": self.target_mass_g,
                "density_offset_frac": p.density_offset_frac,
                "lot_frac": self.lot_frac,
                "calibration_test": (test.to_dict() if (test := self.calibration_test())
                                     is not None else None),
                "row_gain": list(p.row_gain),
                **({"target_mass_row_g": list(self.target_mass_row_g)}
                   if self.switched_rows else {}),
                **({"field_run": self.field_run.truth()} if self.field_run is not None
                   else {})}

    @classmethod
    def scenario_dir(cls) -> Path:
        return Path(__file__).parent / "scenarios"

    @classmethod
    def builtin_controllers(cls) -> dict[str, Callable[[], object]]:
        from plant_emulators.fertilizer.controllers import OpenLoopController, PiFlowController
        return {"pi": PiFlowController, "open-loop": OpenLoopController}
