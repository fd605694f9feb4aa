"""[D]'s depth law between a bus layer and the drive: what the reference does with the values.

Section 2, "CAN adapter", of ``docs/reference-controllers.md``, without the bus: the values a
bus layer decoded go in (:meth:`DepthLaw.set_job`, :meth:`~DepthLaw.inclinometer`,
:meth:`~DepthLaw.ground_speed`, :meth:`~DepthLaw.drive_feedback`), one control step comes out
(:meth:`DepthLaw.step`: the controlword and the target velocity), and what a status frame
reports (:meth:`DepthLaw.status`). The rules are
:class:`reference_controllers.sowing_depth.adapter.DepthController`'s, in its order:

* depth from the inclinometer's X output in mV by eq. 13, filtered ``d += 0.2·(depth - d)``
  per report (the first sets d); invalid while the output's status is not "ok", and while the
  output has not changed for more than ``frozen_after_s``;
* enabled: the terminal says on and automatic, and a ground speed >= ``min_speed_mps`` is
  known (GBSD or GNSS, :mod:`.ground_speed`);
* the fuzzy PID on the valid depth, the roller hold (:mod:`.roller_hold`) while the depth is
  invalid on a running machine, the CiA 402 controlword of :mod:`.cia402_master`.

A bus layer of another database (:mod:`.dbc_adapter`) converts its frames to these values and
these outputs to its frames; the law cannot tell the two apart.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from plant_emulators.sowing_depth.sensors import calibration_depth_mm
from reference_controllers.params import ParamValue
from reference_controllers.sowing_depth.adapter import (
    DEPTH_FILTER,
    GNSS_PORT_ENV,
    MAX_VALID_SPEED_MPS,
    resolve_params,
)
from reference_controllers.sowing_depth.cia402_master import (
    is_fault,
    is_operation_enabled,
    next_controlword,
)
from reference_controllers.sowing_depth.fuzzy_pid import FuzzyPid
from reference_controllers.sowing_depth.ground_speed import NmeaPort, SpeedSources
from reference_controllers.sowing_depth.roller_hold import RollerHold

__all__ = ["DepthLaw", "LawStatus", "LawStep"]


@dataclass(frozen=True)
class LawStep:
    """One control step's outputs: what goes to the drive, and why."""

    controlword: int
    speed_mm_s: float
    valid: bool
    enabled: bool
    frozen: bool


@dataclass(frozen=True)
class LawStatus:
    """What the controller's status frame reports, in the law's units."""

    measured_depth_mm: float
    roller_position_command_mm: float
    state: str
    sensor_fault: bool
    drive_fault: bool
    speed_lost: bool


class DepthLaw:
    """The reference depth law's state and step.

    Parameters
    ----------
    params : mapping, optional
        Overrides of the fuzzy PID's and the adapter's parameters
        (:func:`reference_controllers.sowing_depth.adapter.resolve_params`).

    Raises
    ------
    reference_controllers.params.ParamError
        An unknown parameter or a bad value (named).
    """

    def __init__(self, params: Mapping[str, ParamValue] | None = None) -> None:
        self.core_params, self.adapter_params = resolve_params(params)
        self.core = FuzzyPid(self.core_params)
        self.hold = RollerHold(self.adapter_params.hold())
        self.speeds = SpeedSources(self.adapter_params.speed_timeout_s)
        self.gnss: NmeaPort | None = None
        self.statusword = 0
        #: the drive's Position actual value in mm, None before any
        self.position_mm: float | None = None
        self.holding = False
        self.last_controlword = 0
        self.target_mm = 30.0
        self.terminal_on = False
        self.automatic = False
        self.manual = False
        self.depth_mm: float | None = None
        self.depth_ok = False
        self.last_x_mv: float | None = None
        self.x_changed_at_s = 0.0
        self.steps = 0
        self.speed_mm_s = 0.0
        self.gains = (self.core_params.kp0, self.core_params.ki0, self.core_params.kd0)

    @property
    def now_s(self) -> float:
        return self.steps * self.core_params.period_s

    # --- set-up ---------------------------------------------------------------------------
    def configure(self, env: Mapping[str, str]) -> None:
        """Open the GNSS serial port the rig names in ``AGRIHIL_GNSS_PORT``, if any."""
        path = env.get(GNSS_PORT_ENV)
        if path and self.gnss is None:
            self.gnss = NmeaPort(path)

    def close(self) -> None:
        if self.gnss is not None:
            self.gnss.close()

    # --- values in ------------------------------------------------------------------------
    def set_job(self, target_mm: float, on: bool, automatic: bool, manual: bool) -> None:
        """The terminal's set-point, switch and mode."""
        self.target_mm, self.terminal_on = target_mm, on
        self.automatic, self.manual = automatic, manual

    def inclinometer(self, ok: bool, x_mv: float) -> None:
        """One report of the inclinometer's X output (``ok``: its status says so)."""
        self.depth_ok = ok
        if not ok:
            return
        if x_mv != self.last_x_mv:
            self.last_x_mv, self.x_changed_at_s = x_mv, self.now_s
            self.hold.mark()         # a sign of life: the mean so far is trusted
        depth = calibration_depth_mm(x_mv)
        self.depth_mm = depth if self.depth_mm is None else (
            self.depth_mm + DEPTH_FILTER * (depth - self.depth_mm))

    def ground_speed(self, speed_mps: float) -> None:
        """The tractor's ground speed (a J1939 "not available" reads above the valid range)."""
        valid = 0.0 <= speed_mps <= MAX_VALID_SPEED_MPS
        self.speeds.update("gbsd", speed_mps if valid else None, self.now_s)

    def drive_feedback(self, statusword: int, position_mm: float | None = None) -> None:
        """The drive's statusword, and its position when the PDO carries it."""
        self.statusword = statusword
        if position_mm is not None:
            self.position_mm = position_mm

    # --- the control step -----------------------------------------------------------------
    def frozen(self) -> bool:
        """The inclinometer's X output has not changed for more than ``frozen_after_s``."""
        limit = self.adapter_params.frozen_after_s
        return (limit > 0.0 and self.last_x_mv is not None
                and self.now_s - self.x_changed_at_s > limit + 1e-9)

    def enabled(self) -> bool:
        speed = self.speeds.speed(self.now_s)
        return (self.terminal_on and self.automatic and speed is not None
                and speed >= self.adapter_params.min_speed_mps)

    def step(self) -> LawStep:
        """Run the fuzzy PID once (the step counter moves on in :meth:`end_step`)."""
        if self.gnss is not None:
            for value in self.gnss.poll():
                self.speeds.update("gnss", value, self.now_s)
        controlword = next_controlword(self.statusword, self.last_controlword)
        self.last_controlword = controlword
        frozen = self.frozen()
        drive_on = is_operation_enabled(self.statusword)
        valid = self.depth_mm is not None and self.depth_ok and not frozen and drive_on
        enabled = self.enabled()
        speed, kp, ki, kd = self.core.step(self.target_mm, self.depth_mm or 0.0, valid, enabled)
        # where the roller is held (.roller_hold): track the mean rod position while
        # regulating, drive the rod back to it while the depth is invalid on a running
        # machine, forget it when control is switched off (the core commands 0: it stays)
        self.holding = False
        if enabled and valid:
            if self.position_mm is not None:
                self.hold.track(self.position_mm, self.core_params.period_s)
        elif not enabled:
            self.hold.reset()
        elif drive_on and self.position_mm is not None and self.hold.target_mm is not None:
            self.holding = True
            speed = self.hold.speed(self.position_mm)
        self.speed_mm_s, self.gains = speed, (kp, ki, kd)
        return LawStep(controlword, speed, valid, enabled, frozen)

    def end_step(self) -> None:
        self.steps += 1

    def status(self, step: LawStep) -> LawStatus:
        """The status of this step (before :meth:`end_step`), as the reference reports it."""
        if is_fault(self.statusword):
            state = "fault"
        elif self.manual:
            state = "manual"
        elif step.valid and step.enabled:
            state = "controlling"
        elif is_operation_enabled(self.statusword):
            state = "ready"
        else:
            state = "initialising"
        depth = 0.0 if self.depth_mm is None else min(max(self.depth_mm, -100.0), 200.0)
        # holding: the hold target in whole 0.01 mm (half to even, as the C build); regulating
        # in profile velocity mode there is no position command: 0
        command = 0.0
        if self.holding and self.hold.target_mm is not None:
            command = round(min(max(self.hold.target_mm, 0.0), 100.0) * 100.0) / 100.0
        return LawStatus(round(depth, 1), command, state,
                         self.depth_mm is None or not self.depth_ok or step.frozen,
                         is_fault(self.statusword), self.speeds.speed(self.now_s) is None)
