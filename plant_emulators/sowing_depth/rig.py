"""The sowing-depth rig of [D]: physics, its CAN nodes, GNSS serial port, scenarios and truth."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, ClassVar

import can
import numpy as np

from hil.contract.codec import ContractCodec
from hil.errors import ConfigError
from hil.rig import Rig, RigContext
from plant_emulators.sowing_depth.cia402_objects import ErrorCode
from plant_emulators.sowing_depth.config import SowingDepthRigConfig, load_rig_config
from plant_emulators.sowing_depth.controllers import PiDepthController
from plant_emulators.sowing_depth.devices import (
    DrawWireDevice,
    GnssDevice,
    InclinometerDevice,
    ServoDriveDevice,
    TerminalDevice,
    TractorSpeedDevice,
)
from plant_emulators.sowing_depth.field_run import DEPTH_FIELD_FAULTS, DepthFieldRun, SeedLine
from plant_emulators.sowing_depth.frames import EDS_PATH
from plant_emulators.sowing_depth.gnss_serial import GnssSerialPort, SerialPortError
from plant_emulators.sowing_depth.nmea import GnssReceiver
from plant_emulators.sowing_depth.physics import SowingDepthPlant
from plant_emulators.sowing_depth.sensors import (
    DrawWireSensor,
    Inclinometer,
    calibration_depth_mm,
)

#: The drive's EDS (defined in ``frames``; kept here under its old name for callers)
EDS = EDS_PATH
#: GB/T 20865-2007: for a target of 30 mm or more the qualified band is target ± 10 mm
QUALIFIED_BAND_MM = 10.0


class SowingDepthRig(Rig):
    name = "sowing_depth"
    physics_period_s = 0.001
    trace_period_s = 0.01
    inputs: ClassVar[dict[str, str]] = {
        "target_depth_mm": "depth setpoint from the terminal, mm",
        "enable": "0/1: the terminal enables depth control",
        "manual": "0/1: manual mode (the roller goes to manual_roller_position_mm)",
        "manual_roller_position_mm": "roller position asked in manual mode, mm",
        "ground_speed_mps": "tractor ground speed, m/s",
    }
    faults: ClassVar[dict[str, str]] = {
        "inclinometer_stuck": "the inclinometer output freezes",
        "inclinometer_noisy": "the inclinometer output gets very noisy (loose mounting)",
        "inclinometer_lost": "the inclinometer's analog input node stops sending",
        "inclinometer_open_circuit": "the inclinometer's X output wire breaks (0 mV, status "
                                     "below range)",
        "draw_wire_lost": "the draw-wire sensor stops sending",
        "drive_jammed": "the cylinder rod is blocked (a stone): the drive trips on "
                        "overcurrent or following error",
        "drive_overcurrent": "the drive reports an overcurrent fault",
        "drive_power_lost": "the drive's main power is switched off",
        "gnss_fix_lost": "the GNSS receiver loses its fix (RMC status V, GGA quality 0)",
        "controller_silent": "no frame of the controller reaches the rig (cut wire)",
        **{name: f"field runs under a TC ([tractor] scenarios): {what}"
           for name, what in DEPTH_FIELD_FAULTS.items()},
    }
    plot_groups: ClassVar[list[tuple[str, list[str]]]] = [
        ("depth [mm]", ["target_depth_mm", "mean_true_depth_mm", "sensed_depth_mm"]),
        ("cylinder", ["rod_position_mm", "rod_velocity_mm_s"]),
        ("drive", ["drive_statusword", "drive_error_code"]),
        ("ground speed [m/s]", ["ground_speed_mps"]),
    ]

    @classmethod
    def load_config(cls, overrides: Mapping[str, Any] | None = None, *,
                    source: str = "") -> SowingDepthRigConfig:
        return load_rig_config(overrides=_without_binding(overrides)[0], source=source)

    @classmethod
    def bus_contract(cls, overrides: Mapping[str, Any] | None = None,
                     source: str = "") -> Any:
        """The rig's bus contract (quantities, binding in force, nodes) under ``overrides``."""
        from plant_emulators.sowing_depth.frames import bus_contract

        rest, binding = _without_binding(overrides)
        return bus_contract(load_rig_config(overrides=rest, source=source), binding)

    @staticmethod
    def contract_codec(config: SowingDepthRigConfig, binding_file: str = "") -> ContractCodec:
        """The codec of the binding in force (J1939 frames: unused bits sent as 1s, as the
        rig's own codec always did)."""
        from plant_emulators.sowing_depth.frames import bus_contract

        return ContractCodec.for_contract(bus_contract(config, binding_file), padding="always")

    def __init__(self, ctx: RigContext, config: SowingDepthRigConfig | None = None) -> None:
        super().__init__(ctx)
        overrides, binding_file = _without_binding(ctx.config_overrides)
        cfg = config or load_rig_config(overrides=overrides, source=ctx.config_source)
        self.config = cfg
        wiring = cfg.wiring
        self.control_period_s = wiring.sync_period_ms / 1000.0
        plant_rng, incl_rng, wire_rng, gnss_rng = ctx.rng.spawn(4)
        self.plant = SowingDepthPlant(cfg, plant_rng)
        self.codec = self.contract_codec(cfg, binding_file)
        self.inclinometer = Inclinometer(cfg.inclinometer, incl_rng)
        self.draw_wire = DrawWireSensor(cfg.draw_wire, wire_rng)
        self.receiver = GnssReceiver(cfg.gnss, gnss_rng)
        self.gnss = GnssSerialPort(self.receiver, self.plant, note=ctx.note)
        self.drive = ServoDriveDevice(self.plant, wiring.drive_node_id, str(EDS))
        self.terminal = TerminalDevice(self.codec, wiring.depth_setpoint_period_ms / 1000.0)
        self.incl_device = InclinometerDevice(self.plant, self.inclinometer, self.codec,
                                              wiring.inclinometer_period_ms / 1000.0)
        tractor = ctx.scenario_tractor    # the tractor table only: the run may still be held
        machine = cfg.machine
        #: a field run under a Task Controller (field_run.py): the rig is an ISOBUS tractor
        #: whose TECU and TC replace the terminal's DepthSetpoint and the speed frame
        self.field_run = (DepthFieldRun(tractor, SeedLine(
            machine.rows * machine.row_spacing_mm / 1000.0,
            -machine.tractor_rear_axle_ahead_of_seed_m)) if tractor is not None else None)
        self._pose = self.field_run.pose(0.0) if self.field_run is not None else None
        tractor_side = ([self.field_run.device] if self.field_run is not None else
                        [TractorSpeedDevice(self.plant, self.codec,
                                            wiring.ground_speed_period_ms / 1000.0),
                         self.terminal])
        self.devices = [
            self.drive,
            self.incl_device,
            DrawWireDevice(self.plant, self.draw_wire, self.codec,
                           wiring.draw_wire_period_ms / 1000.0),
            *tractor_side,
            GnssDevice(self.gnss),
        ]
        self.controller_silent = False
        if self.field_run is not None:
            #: field runs trace where the seed line is and what the map asks there
            self._TRACE_LAYOUT = (*type(self)._TRACE_LAYOUT, *_FIELD_TRACES)
        self._truth: list = []
        self._final_truth: dict[str, np.ndarray] | None = None
        self._since_drain_s = 0.0

    # --- physics --------------------------------------------------------------------------
    def advance(self, n: int, dt: float) -> None:
        if self.field_run is not None:
            # the path is the truth of motion: the planter moves at its speed (the GNSS line
            # reports it, the TECU too)
            self._pose = self.field_run.pose(self.plant.time_s)
            self.plant.ground_speed_mps = self._pose.speed_m_s
        self.plant.advance(n, dt)
        self._since_drain_s += n * dt
        # keep the plant's truth lists short: draining 30 s at once took ~6 ms in one tick
        if self._since_drain_s >= 5.0:
            self._since_drain_s = 0.0
            self._truth.append(self.plant.drain_truth())

    # --- scenario ---------------------------------------------------------------------------
    def set_input(self, name: str, value: float, time_s: float) -> None:
        t = self.terminal
        if name == "target_depth_mm":
            t.target_depth_mm = value
        elif name == "enable":
            t.enable = bool(value)
        elif name == "manual":
            t.manual = bool(value)
        elif name == "manual_roller_position_mm":
            t.manual_roller_position_mm = value
        elif name == "ground_speed_mps":
            if value < 0:
                raise ConfigError(f"ground speed must be >= 0, got {value}", key=name)
            self.plant.ground_speed_mps = value
        else:
            raise ConfigError(f"unknown input {name!r}", key=name)

    def set_fault(self, name: str, active: bool, target: int | None, time_s: float) -> None:
        if name == "inclinometer_stuck":
            self.inclinometer.stuck = active
        elif name == "inclinometer_noisy":
            self.inclinometer.noisy = active
        elif name == "inclinometer_lost":
            self.incl_device.lost = active
        elif name == "inclinometer_open_circuit":
            self.incl_device.x_open_circuit = active
        elif name == "draw_wire_lost":
            self.draw_wire.lost = active
        elif name == "drive_jammed":
            self.plant.cylinder.jammed = active
        elif name == "drive_overcurrent":
            if active:
                self.plant.drive.inject_fault(ErrorCode.CONTINUOUS_OVER_CURRENT)
            else:
                self.plant.drive.clear_injected_fault(ErrorCode.CONTINUOUS_OVER_CURRENT)
        elif name == "drive_power_lost":
            self.plant.drive.main_power = not active
        elif name == "gnss_fix_lost":
            self.receiver.fix_lost = active
        elif name == "controller_silent":
            self.controller_silent = active
        elif name in DEPTH_FIELD_FAULTS:
            if self.field_run is None:
                raise ConfigError(f"{name} needs a field run under a Task Controller (a "
                                  f"scenario with a [tractor] table)", key=name)
            self.field_run.set_fault(name, active, time_s)
        else:
            raise ConfigError(f"unknown fault {name!r}", key=name)

    def admits(self, msg: can.Message) -> bool:
        return not self.controller_silent

    #: a CiA 402 master answers SYNC with RPDO1 (profile position) or RPDO2 (velocity)
    await_any_command = True
    #: what makes an RPDO the step's command: it maps a target (CiA 402 target position,
    #: target velocity)
    COMMAND_OBJECTS = (0x607A, 0x60FF)

    def command_ids(self) -> frozenset[int]:
        """The drive's RPDOs that carry a target, as the master has configured them (a master
        that remaps its PDOs at boot moves them: the lockstep step follows); the EDS's
        RPDO1/RPDO2 (0x200/0x300 + node) until it does."""
        drive = getattr(self, "drive", None)
        ids = drive.rpdo_ids_mapping(self.COMMAND_OBJECTS) if drive is not None else None
        if ids:
            return ids
        node = self.config.wiring.drive_node_id
        return frozenset({0x200 + node, 0x300 + node})

    # --- records ------------------------------------------------------------------------------
    #: (name, unit) of every traced signal, in :meth:`trace_row` order
    _TRACE_LAYOUT: ClassVar[tuple[tuple[str, str], ...]] = (
        ("target_depth_mm", "mm"), ("mean_true_depth_mm", "mm"), ("sensed_depth_mm", "mm"),
        ("rod_position_mm", "mm"), ("rod_velocity_mm_s", "mm/s"), ("rod_force_n", "N"),
        ("motor_current_a", "A"), ("cover_soil_mm", "mm"), ("arm_angle_deg", "deg"),
        ("machine_pitch_deg", "deg"), ("ground_speed_mps", "m/s"), ("distance_m", "m"),
        ("drive_statusword", "1"), ("drive_error_code", "1"))

    def trace_signals(self) -> dict[str, tuple[float, str]]:
        return {name: (value, unit) for (name, unit), value in
                zip(self._TRACE_LAYOUT, self.trace_row(), strict=True)}

    def trace_row(self) -> tuple[float, ...]:
        """The traced values in :attr:`_TRACE_LAYOUT` order (what :meth:`trace_signals`
        pairs with the names and units)."""
        p = self.plant
        drive = p.drive
        last_x_mv = self.incl_device.last_x_mv
        if self.field_run is not None:
            pose = self._pose
            assert pose is not None
            east, north = self.field_run.seed_point(pose)
            prescribed = self.field_run.prescribed_depth(pose)
            return (prescribed, p.mean_true_depth_mm,
                    calibration_depth_mm(last_x_mv) if last_x_mv else float("nan"),
                    p.rod_position_mm, p.rod_velocity_mm_s, p.rod_force_n, p.motor_current_a,
                    p.cover_soil_mm, p.arm_angle_deg, p.machine_pitch_deg, p.ground_speed_mps,
                    p.distance_m, float(drive.statusword), float(drive.error_code),
                    east, north, pose.heading_deg, 1.0 if pose.kind == "pass" else 0.0)
        return (self.terminal.target_depth_mm, p.mean_true_depth_mm,
                calibration_depth_mm(last_x_mv) if last_x_mv else float("nan"),
                p.rod_position_mm, p.rod_velocity_mm_s, p.rod_force_n, p.motor_current_a,
                p.cover_soil_mm, p.arm_angle_deg, p.machine_pitch_deg, p.ground_speed_mps,
                p.distance_m, float(drive.statusword), float(drive.error_code))

    def truth_arrays(self) -> dict[str, np.ndarray]:
        """Every truth cell of the run (one per 10 mm of travel, per row)."""
        if self._final_truth is None:
            cells = [*self._truth, self.plant.drain_truth()]
            self._truth = []
            self._final_truth = {
                name: np.concatenate([getattr(c, name) for c in cells])
                for name in ("distance_m", "depth_mm", "outlier_kind", "ground_speed_mps",
                             "rod_position_mm")}
        return self._final_truth

    def truth(self) -> dict[str, object]:
        """Seed depth over every truth cell (not yet sampled as [D] samples: the suites do),
        and what reached the DUT of the GNSS receiver's output (``gnss_epochs``)."""
        cells = self.truth_arrays()
        depth = cells["depth_mm"]
        # the GNSS serial line's epochs: written, overrun, dropped, late, unread bytes
        gnss = {"gnss_epochs": self.gnss.counts(),
                **({"field_run": self.field_run.truth()} if self.field_run is not None
                   else {})}
        if depth.size == 0:
            return {"cells": 0, **gnss}
        target = self.terminal.target_depth_mm
        inside = np.abs(depth - target) <= QUALIFIED_BAND_MM
        return {"cells": int(depth.shape[0]), "rows": int(depth.shape[1]),
                "distance_m": float(cells["distance_m"][-1]),
                "mean_depth_mm": float(depth.mean()), "sd_mm": float(depth.std(ddof=1)),
                "pass_rate_pct": float(100.0 * inside.mean()),
                "outlier_fraction_pct": float(100.0 * (cells["outlier_kind"] > 0).mean()),
                **gnss}

    def physics_engines(self) -> dict[str, str]:
        return {"plant": self.plant.engine}

    def dut_environment(self) -> dict[str, str]:
        return {"AGRIHIL_GNSS_PORT": self.gnss.path}

    def close(self) -> None:
        self.gnss.close()

    def ready_to_hold(self) -> bool:
        """The GNSS line is the rig's only state outside the process: it is held when the
        DUT has read everything written to it (or the copy would not start from that)."""
        return self.gnss.port.settled_unread_bytes() == 0

    def resume_held(self) -> None:
        """The line empty again, as it was when held (a run that went on from there may
        have left its last epochs unread on it).

        Raises
        ------
        SerialPortError
            Bytes are still there after the flush (the copy would not start as held).
        """
        port = self.gnss.port
        port.settled_unread_bytes()     # what is written is in the queue, to be flushed
        port.discard_unread()
        left = port.settled_unread_bytes()
        if left:
            raise SerialPortError(f"{port.path}: {left} bytes still unread after a flush: a "
                                  "run cannot continue from its checkpoint")

    @classmethod
    def scenario_dir(cls) -> Path:
        return Path(__file__).parent / "scenarios"

    @classmethod
    def builtin_controllers(cls) -> dict[str, Callable[[], object]]:
        return {"pi": PiDepthController}


#: what a field run traces besides the rest: the seed line's middle (local m), the heading, and
#: whether the path is on a pass (1) or a turn (0); target_depth_mm is the map's depth there
_FIELD_TRACES = (("seed_east_m", "m"), ("seed_north_m", "m"), ("heading_deg", "deg"),
                 ("on_pass", "1"))


def _without_binding(overrides: Mapping[str, Any] | None) -> tuple[dict[str, Any], str]:
    """``overrides`` without ``wiring.binding_file`` (a profile's ``[wiring] binding``, which
    the rig's config does not hold), and that file ("" when none)."""
    rest = dict(overrides or {})
    wiring = rest.get("wiring")
    if not isinstance(wiring, Mapping) or "binding_file" not in wiring:
        return rest, ""
    wiring = dict(wiring)
    binding = str(wiring.pop("binding_file"))
    if wiring:
        rest["wiring"] = wiring
    else:
        del rest["wiring"]
    return rest, binding
