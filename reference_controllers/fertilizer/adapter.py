"""[F]'s flow controller on CAN: the rig's frames in, the analog module's command out.

Section 1, "CAN adapter", of ``docs/reference-controllers.md``. Every frame is decoded and
encoded through the fertilizer rig's DBC (:class:`FertilizerDatabase`); the control law is one
of the pure cores of :mod:`reference_controllers.fertilizer.piecewise_pid`.

* reads FertSetpoint 0x210, FlowModule1-4 0x181-0x184, GroundWheelSpeed 0x185, PGN 65096 and
  PGN 65097 (matched by PGN), SYNC 0x080, and MeterCalibration 0x310 when the terminal sends
  one: the operator's calibration test of the lot replaces ``ff_coeff`` from then on
  (:mod:`reference_controllers.fertilizer.calibration`; ``use_calibration = 0`` ignores it);
* one control step per SYNC (lockstep, ``step_on_sync``) or per :meth:`on_tick` (a daemon's
  own timer);
* each step writes AnalogOutputCommand 0x220 (Ch1 mV = round(volts·1000)) and the heartbeat
  0x710 (Operational); every 10th step (the first included) ControllerStatus 0x190.

Terminal mode 2 (constant speed) runs the open-loop law whatever the controller; a change of
terminal mode resets the closed-loop core, as a target of 0 does.
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from dataclasses import dataclass, replace

import can

from hil.dut import Controller
from hil.errors import FrameError
from plant_emulators.fertilizer.config import FertilizerRigConfig, load_rig_config
from plant_emulators.fertilizer.frames import (
    PGN_GROUND_BASED_SPEED,
    PGN_WHEEL_BASED_SPEED,
    FertilizerDatabase,
    NmtState,
    j1939_pgn,
)
from reference_controllers.fertilizer.calibration import ff_coeff_from_test
from reference_controllers.fertilizer.piecewise_pid import (
    OpenLoop,
    PiecewisePid,
    PiecewisePidParams,
)
from reference_controllers.fertilizer.rows import FlowRows
from reference_controllers.fertilizer.speeds import SPEED_SOURCES, GroundSpeedFirst, valid_speed
from reference_controllers.params import ParamError, ParamValue, field_names, override, split

LAWS = ("physical", "paper-literal", "open-loop")
MODE_FIELD, MODE_BENCH, MODE_CONSTANT = 0, 1, 2
SYNC_ID = 0x080
STATUS_EVERY = 10
OPEN_LOOP_KEYS = ("ff_coeff", "ff_exponent", "shaft_rpm_per_v", "v_max", "ff_linear_below_rpm")


@dataclass(frozen=True)
class FlowAdapterParams:
    """The adapter's own parameters: report staleness, the control period and how fresh a
    ground-based speed must be to be used before the terminal's source (s; 0: the terminal's
    source alone; :mod:`reference_controllers.fertilizer.speeds`) and whether the terminal's
    calibration test (MeterCalibration) replaces ``ff_coeff`` (1) or is ignored (0)."""

    stale_after_s: float = 2.5
    period_s: float = 0.1
    ground_speed_first_s: float = 0.3
    use_calibration: float = 1.0

    def __post_init__(self) -> None:
        if not self.period_s > 0.0:
            raise ValueError(f"period_s must be > 0, got {self.period_s}")
        if not self.stale_after_s >= 0.0:
            raise ValueError(f"stale_after_s must be >= 0, got {self.stale_after_s}")
        if not self.ground_speed_first_s >= 0.0:
            raise ValueError(f"ground_speed_first_s must be >= 0, got "
                             f"{self.ground_speed_first_s}")
        if self.use_calibration not in (0.0, 1.0):
            raise ValueError(f"use_calibration must be 0 or 1, got {self.use_calibration}")


def resolve_params(law: str | None, params: Mapping[str, ParamValue] | None) -> tuple[
        str, PiecewisePidParams, FlowAdapterParams]:
    """(law, core parameters, adapter parameters) from a law name and ``key=value`` pairs.

    ``params`` may name the law as ``mode``; the open-loop law takes only the feedforward keys.

    Raises
    ------
    ParamError
        Unknown law or parameter name (named), or a bad value.
    """
    values = dict(params or {})
    mode = values.pop("mode", None)
    if mode is not None and law is not None and str(mode) != law:
        raise ParamError(f"parameter 'mode' = {mode!r} contradicts the law {law!r}")
    law = law or (str(mode) if mode is not None else "physical")
    if law not in LAWS:
        raise ParamError(f"unknown fertilizer law {law!r} (known: {', '.join(LAWS)})")
    adapter_values, core_values = split(values, field_names(FlowAdapterParams))
    adapter = override(FlowAdapterParams(), adapter_values)
    if law == "open-loop":
        extra = sorted(set(core_values) - set(OPEN_LOOP_KEYS))
        if extra:
            known = ", ".join([*OPEN_LOOP_KEYS, *field_names(FlowAdapterParams)])
            raise ParamError(f"unknown parameter {extra[0]!r} for the open-loop law "
                             f"(known: {known})")
        return law, override(PiecewisePidParams.physical(), core_values), adapter
    core_values.pop("mode", None)
    return law, override(PiecewisePidParams.default(law), core_values), adapter


class FlowController(Controller):
    """The reference flow controller of [F] as an in-process controller.

    Parameters
    ----------
    law : str, optional
        ``"physical"`` (default), ``"paper-literal"`` or ``"open-loop"``; may also be given
        as the parameter ``mode``.
    params : mapping, optional
        Overrides of :class:`PiecewisePidParams` fields and of ``stale_after_s``,
        ``period_s`` (a DUT profile's ``[parameters]``).
    step_on_sync : bool
        Run a control step on each SYNC (lockstep); False: only :meth:`on_tick` steps.
    **more_params
        More parameters as keywords (how ``hil`` hands a profile's ``[parameters]`` to a
        ``launch.inprocess`` class); unknown names raise
        :class:`~reference_controllers.params.ParamError` naming them.
    """

    default_law: str | None = None

    def __init__(self, law: str | None = None, params: Mapping[str, ParamValue] | None = None,
                 *, step_on_sync: bool = True, rig_config: FertilizerRigConfig | None = None,
                 **more_params: ParamValue) -> None:
        self.law, self.core_params, self.adapter_params = resolve_params(
            law or self.default_law, {**(params or {}), **more_params})
        self.name = ("fertilizer-open-loop" if self.law == "open-loop"
                     else f"fertilizer-piecewise-pid-{self.law}")
        self.step_on_sync = step_on_sync
        self.db = FertilizerDatabase.from_config(rig_config or load_rig_config())
        self.open_loop = OpenLoop(self.core_params)
        self.closed_loop = None if self.law == "open-loop" else PiecewisePid(self.core_params)
        self.ids = {name: self.db.frame_id(name)
                    for name in ("FertSetpoint", "GroundWheelSpeed", "MeterCalibration")}
        self.flow_rows = {self.db.frame_id(f"FlowModule{i}"): i for i in range(1, 5)}
        self.rows = FlowRows(self.adapter_params.stale_after_s, self.adapter_params.period_s)
        self.setpoint: dict[str, float] = {}
        self.speeds = {"hall": 0.0, "wheel": 0.0, "ground": 0.0}
        self.ground_first = GroundSpeedFirst(self.adapter_params.ground_speed_first_s,
                                             self.adapter_params.period_s)
        self.steps = 0
        self.active_mode: int | None = None
        self.volts = 0.0
        self.segment = 0

    # --- frames in ----------------------------------------------------------------------
    def on_start(self) -> list[can.Message]:
        return [self.db.heartbeat("ControllerHeartbeat", NmtState.BOOT_UP)]

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.is_error_frame or msg.is_remote_frame:
            return []
        can_id = msg.arbitration_id
        if not msg.is_extended_id and can_id == SYNC_ID:
            return self.step() if self.step_on_sync else []
        with contextlib.suppress(FrameError):   # an undecodable frame is ignored, as on a bus
            self._take(msg)
        return []

    def _take(self, msg: can.Message) -> None:
        can_id = msg.arbitration_id
        if msg.is_extended_id:
            pgn = j1939_pgn(can_id)
            if pgn == PGN_WHEEL_BASED_SPEED:
                self._speed("wheel", self.db.decode(msg)[1]["WheelBasedMachineSpeed"])
            elif pgn == PGN_GROUND_BASED_SPEED:
                self._speed("ground", self.db.decode(msg)[1]["GroundBasedMachineSpeed"])
        elif can_id in self.flow_rows:
            s = self.db.decode(msg)[1]
            self.rows.report(self.flow_rows[can_id], float(s["Flow"]),
                             bool(s["BaselineReady"]), bool(s["AdcOverrange"]), self.steps)
        elif can_id == self.ids["FertSetpoint"]:
            self.setpoint = {k: float(v) for k, v in self.db.decode(msg)[1].items()}
        elif can_id == self.ids["GroundWheelSpeed"]:
            self._speed("hall", self.db.decode(msg)[1]["WheelSpeed"])
        elif can_id == self.ids["MeterCalibration"] and self.adapter_params.use_calibration:
            s = self.db.decode(msg)[1]
            self.calibrate(float(s["GramsPerRev"]), float(s["TestShaftSpeed"]))

    def calibrate(self, grams_per_rev: float, shaft_rpm: float) -> None:
        """The operator's calibration test: the feedforward map's coefficient from its grams
        per revolution at its shaft speed, for both laws; a frame without a usable test
        changes nothing."""
        p = self.core_params
        coeff = ff_coeff_from_test(grams_per_rev, shaft_rpm, p.ff_exponent,
                                   p.ff_linear_below_rpm)
        if coeff is None or coeff == p.ff_coeff:
            return
        self.core_params = replace(p, ff_coeff=coeff)
        self.open_loop.params = self.core_params
        if self.closed_loop is not None:
            self.closed_loop.params = self.core_params

    def _speed(self, source: str, value: float) -> None:
        value = float(value)
        self.speeds[source] = value if valid_speed(value) else 0.0
        if source == "ground":
            self.ground_first.heard(value, self.steps)

    # --- the control step -----------------------------------------------------------------
    @property
    def enabled(self) -> bool:
        return bool(self.setpoint.get("Enable", 0.0))

    @property
    def terminal_mode(self) -> int:
        return int(self.setpoint.get("Mode", MODE_BENCH))

    def target_gps(self) -> float:
        """Target flow per row: bench TargetFlow, or field 0.1·M·D·v / ActiveRows (eq. 1)."""
        sp = self.setpoint
        if not sp or not self.enabled:
            return 0.0
        if self.terminal_mode == MODE_FIELD:
            source = int(sp.get("SpeedSource", 0))
            speed = self.ground_first.field_speed(
                self.speeds, SPEED_SOURCES[source] if source < len(SPEED_SOURCES) else None,
                self.steps)
            rows = max(1, int(sp.get("ActiveRows", 4)))
            return 0.1 * sp["TargetRate"] * sp["WorkingWidth"] * speed / rows
        return float(sp.get("TargetFlow", 0.0))

    def setpoint_rows(self) -> int:
        """FertSetpoint.ActiveRows: rows 1..N meter (4 until a setpoint says otherwise)."""
        return max(1, int(self.setpoint.get("ActiveRows", 4)))

    def on_tick(self) -> list[can.Message]:
        """One free-running control step (a daemon's timer, not SYNC)."""
        return self.step()

    def step(self) -> list[can.Message]:
        """Run the law once and return the frames of this step."""
        target = self.target_gps()
        mode = self.terminal_mode
        if mode != self.active_mode:
            if self.closed_loop is not None:
                self.closed_loop.reset()
            self.active_mode = mode
        m = self.rows.measure(target, self.steps, self.setpoint_rows())
        law = self.open_loop if (mode == MODE_CONSTANT or self.closed_loop is None) \
            else self.closed_loop
        self.volts, self.segment = law.step(target, m.measured_gps, m.has_measurement,
                                            m.new_report)
        # the command frame goes last: in lockstep it closes the step (the rig's SYNC barrier
        # waits for it), so the status and heartbeat must be on the bus before it
        out: list[can.Message] = []
        if self.steps % STATUS_EVERY == 0:
            closed = law is self.closed_loop
            out.append(self.db.controller_status(
                target_flow_gps=min(max(target, 0.0), 250.0),
                measured_flow_gps=min(m.measured_gps, 250.0) if m.has_measurement else 0.0,
                command_v=self.volts, pid_segment=self.segment, mode=mode,
                enabled=self.enabled,
                sensor_fault=closed and self.enabled and not m.has_measurement,
                counter=self.steps))
        out.append(self.db.heartbeat("ControllerHeartbeat", NmtState.OPERATIONAL))
        out.append(self.db.analog_output_command(ch1_mv=round(self.volts * 1000.0)))
        self.steps += 1
        return out


class OpenLoopFlowController(FlowController):
    """[F]'s constant-speed baseline (section 1c) as its own controller class."""

    default_law = "open-loop"
