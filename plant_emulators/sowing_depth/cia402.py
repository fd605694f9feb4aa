"""CiA 402 drive logic of the servo electric cylinder: state machine, modes, monitoring.

Pure logic, no bus. The rig's CANopen node (``canopen.LocalNode``) forwards SDO and RPDO writes
to :meth:`Cia402Drive.write`, reads objects for SDO uploads and TPDOs with :meth:`Cia402Drive.read`,
and calls :meth:`Cia402Drive.step` once per physics step; the drive then moves the
:class:`~plant_emulators.sowing_depth.cylinder.ServoCylinder` it owns.

The state machine's tables are in :mod:`.cia402_states`, the object dictionary (types, access,
units: position 0.01 mm) in :mod:`.cia402_objects`; this module is the drive that runs them.

Behaviour
---------
* Transitions 0-16 of CiA 402; 1 (after ``boot_time_ms``), 12 (after a quick stop with option
  code 0-2), 13 (on a fault) and 14 (after the fault reaction) are automatic; 15 needs a rising
  edge of controlword bit 7 and the fault's cause gone.
* Controlwords take effect when written (the state machine is event driven); set-points latched
  by bit 4 take effect at the next :meth:`Cia402Drive.step`, after every object of the same PDO
  has been written, as on a drive that samples its inputs once per cycle.
* Profile position (1): bit 4 new set-point with the set-point-acknowledge handshake (bit 12),
  bit 5 change set immediately (else one set-point is buffered), bit 6 relative (to the previous
  target), bit 8 halt; trapezoidal profile from 0x6081/0x6083/0x6084; targets clipped to 0x607D
  (bit 11); target reached (bit 10) after 0x6067 for 0x6068; following error (bit 13 and fault
  0x8611) beyond 0x6065 for 0x6066. The position loop adds ``position_loop_gain_per_s`` times
  the following error to the profile velocity.
* Profile velocity (3): ramp to 0x60FF, braked so the rod stops at the software limits (bit 11);
  target reached within 0x606D for 0x606E; bit 12 "speed = 0" within 0x606F for 0x6070.
* Force limit (0x6072, at most the 9,806.65 N rating): when the torque is clipped the warning
  bit 7 is set and an overload integral grows; at 0x2002 ms it faults (0x2310); it decays at the
  same rate once below the limit, and fault reset is accepted below
  ``overload_reset_fraction`` of 0x2002.
* Disabling (transitions 5, 8, 9, 10) engages the holding brake at once; quick stop and fault
  reaction ramp down first (0x605A codes 0, 1, 2, 5, 6; 0x605E codes 0, 1, 2).

Example
-------
>>> from plant_emulators.sowing_depth.config import load_rig_config
>>> from plant_emulators.sowing_depth.cylinder import ServoCylinder
>>> cfg = load_rig_config()
>>> drive = Cia402Drive(cfg.drive, ServoCylinder(cfg.motor, cfg.cylinder))
>>> drive.state.value
'NOT READY TO SWITCH ON'
>>> for _ in range(20):          # boot_time_ms = 20
...     drive.step(0.001)
>>> drive.state.value
'SWITCH ON DISABLED'
>>> for cw in (0x06, 0x07, 0x0F):
...     drive.write(0x6040, 0, cw)
>>> drive.state.value, hex(drive.read(0x6041, 0))
('OPERATION ENABLED', '0x237')
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial
from types import ModuleType

from plant_emulators.sowing_depth.cia402_objects import (
    DATA_TYPE_RANGES,
    MODE_NO_MODE,
    MODE_PROFILE_POSITION,
    MODE_PROFILE_VELOCITY,
    OBJECTS,
    POSITION_UNIT_MM,
    SI_UNIT_POSITION,
    SI_UNIT_VELOCITY,
    SUPPORTED_DRIVE_MODES,
    SUPPORTED_MODES,
    DriveObjectError,
    ErrorCode,
    ObjectSpec,
    clip_to_type,
    increments_to_mm,
    mm_to_increments,
)
from plant_emulators.sowing_depth.cia402_states import (
    CW_CHANGE_SET_IMMEDIATELY,
    CW_FAULT_RESET,
    CW_HALT,
    CW_NEW_SET_POINT,
    CW_RELATIVE,
    POWERED_STATES,
    STATE_BITS,
    SW_INTERNAL_LIMIT,
    SW_OP_SPECIFIC_12,
    SW_OP_SPECIFIC_13,
    SW_REMOTE,
    SW_TARGET_REACHED,
    SW_VOLTAGE_ENABLED,
    SW_WARNING,
    Command,
    DriveState,
    decode_command,
    transitions,
)
from plant_emulators.sowing_depth.config import DriveConfig
from plant_emulators.sowing_depth.cylinder import ServoCylinder
from plant_emulators.sowing_depth.motion_profile import MotionProfile

__all__ = [
    "MODE_NO_MODE",
    "MODE_PROFILE_POSITION",
    "MODE_PROFILE_VELOCITY",
    "OBJECTS",
    "POSITION_UNIT_MM",
    "Cia402Drive",
    "Command",
    "DriveObjectError",
    "DriveState",
    "ErrorCode",
    "ObjectSpec",
    "decode_command",
]

_QUICK_STOP_CODES = (0, 1, 2, 5, 6)
_FAULT_REACTION_CODES = (0, 1, 2)
_mm = increments_to_mm
_inc = mm_to_increments


class Cia402Drive:
    """CiA 402 drive of the servo electric cylinder (profile position and profile velocity).

    Parameters
    ----------
    config : DriveConfig
        Power-on values of the drive parameters.
    cylinder : ServoCylinder
        The cylinder the drive moves in :meth:`step`.

    Notes
    -----
    Access is either object by object (:meth:`read`, :meth:`write`, the interface for a
    ``canopen.LocalNode``'s read/write callbacks: integers in object-dictionary units) or through
    the typed properties (:attr:`state`, :attr:`statusword`, :attr:`error_code` …). Every object
    the drive owns is in :data:`OBJECTS`; the others (0x1000-0x1A03 communication objects) belong
    to the CANopen node. Faults and fault resets also queue EMCY events, collected with
    :meth:`pop_emcy_events`.
    """

    def __init__(self, config: DriveConfig, cylinder: ServoCylinder) -> None:
        self.cylinder = cylinder
        self._state = DriveState.NOT_READY_TO_SWITCH_ON
        self._boot_left_s = config.boot_time_ms * 1e-3
        self._controlword = 0
        self._mode = MODE_NO_MODE
        self._main_power = True
        self._error_code = 0
        self._injected: set[int] = set()
        self._emcy: list[tuple[int, int]] = []
        self._profile = MotionProfile(cylinder.position_mm)
        # Profile-position state.
        self._sp_edge = False
        self._sp_ack = False
        self._active_target: float | None = None
        self._buffered_target: float | None = None
        self._last_target_mm = cylinder.position_mm
        self._target_clipped = False
        # Monitoring.
        self._fe_time_s = 0.0
        self._following_error = False
        self._overload_s = 0.0
        self._window_time_s = 0.0
        self._threshold_time_s = 0.0
        self._target_reached = False
        self._speed_zero = False
        self._internal_limit = False
        self._hold_mm = cylinder.position_mm
        # Parameters (object-dictionary integers).
        self._od: dict[tuple[int, int], int] = {
            (0x2002, 0): _round_u(config.overload_time_ms),
            (0x605A, 0): config.quick_stop_option_code,
            (0x605E, 0): config.fault_reaction_option_code,
            (0x6065, 0): _inc(config.following_error_window_mm),
            (0x6066, 0): _round_u(config.following_error_timeout_ms),
            (0x6067, 0): _inc(config.position_window_mm),
            (0x6068, 0): _round_u(config.position_window_time_ms),
            (0x606D, 0): _inc(config.velocity_window_mm_per_s),
            (0x606E, 0): _round_u(config.velocity_window_time_ms),
            (0x606F, 0): _inc(config.velocity_threshold_mm_per_s),
            (0x6070, 0): _round_u(config.velocity_threshold_time_ms),
            (0x6072, 0): _round_u(1000.0 * cylinder.torque_max_n_m / cylinder.rated_torque_n_m),
            (0x6075, 0): _round_u(1000.0 * cylinder.rated_current_a),
            (0x6076, 0): _round_u(1000.0 * cylinder.rated_torque_n_m),
            (0x607A, 0): _inc(cylinder.position_mm),
            (0x607D, 0): 2,
            (0x607D, 1): _inc(config.software_position_limit_min_mm),
            (0x607D, 2): _inc(config.software_position_limit_max_mm),
            (0x607F, 0): _inc(cylinder.rod_speed_max_mm_per_s),
            (0x6080, 0): _round_u(cylinder.rated_speed_rpm),
            (0x6081, 0): _inc(config.profile_velocity_mm_per_s),
            (0x6083, 0): _inc(config.profile_acceleration_mm_per_s2),
            (0x6084, 0): _inc(config.profile_deceleration_mm_per_s2),
            (0x6085, 0): _inc(config.quick_stop_deceleration_mm_per_s2),
            (0x6086, 0): 0,
            (0x60A8, 0): SI_UNIT_POSITION,
            (0x60A9, 0): SI_UNIT_VELOCITY,
            (0x60FF, 0): 0,
            (0x6502, 0): SUPPORTED_DRIVE_MODES,
        }
        self._kp_per_s = config.position_loop_gain_per_s
        self._overload_reset_fraction = config.overload_reset_fraction
        self._apply_parameters()

    # ------------------------------------------------------------------ object dictionary
    def read(self, index: int, subindex: int) -> int:
        """Value of object ``index:subindex`` in object-dictionary units.

        Raises
        ------
        DriveObjectError
            If the drive does not own the object (abort code 0x06020000 / 0x06090011).
        """
        key = (index, subindex)
        if key not in OBJECTS:
            self._spec_of(index, subindex)          # raises the right abort code
        getter = _COMPUTED.get(key)
        if getter is not None:
            return getter(self)
        return self._od[key]

    def reader(self, index: int, subindex: int) -> Callable[[], int]:
        """A function of nothing giving :meth:`read`'s value of object ``index:subindex`` now.

        For the rig's CANopen node, which samples the same few objects into TPDOs at every
        SYNC (:meth:`hil.rig.canopen_device.CanopenDevice.app_reader`): the object is looked
        up once here rather than at each read.

        Raises
        ------
        DriveObjectError
            If the drive does not own the object (as :meth:`read`).
        """
        key = (index, subindex)
        if key not in OBJECTS:
            self._spec_of(index, subindex)          # raises the right abort code
        getter = _COMPUTED.get(key)
        if getter is not None:
            return partial(getter, self)
        return partial(self._od.__getitem__, key)

    def write(self, index: int, subindex: int, value: int) -> None:
        """Write ``value`` (object-dictionary units) to object ``index:subindex``.

        Raises
        ------
        DriveObjectError
            Unknown object (0x06020000 / 0x06090011), read-only or constant object
            (0x06010002), value outside the data type (0x06070010 is not used: the value is an
            integer) or outside the allowed values (0x06090030).
        """
        spec = self._spec_of(index, subindex)
        if spec.access != "rw":
            raise DriveObjectError(
                f"0x{index:04X}:{subindex:02X} {spec.name} is read-only",
                abort_code=0x06010002)
        if isinstance(value, bool) or not isinstance(value, int):
            raise DriveObjectError(
                f"0x{index:04X}:{subindex:02X} {spec.name}: expected an integer, got {value!r}",
                abort_code=0x06090030)
        lo, hi = DATA_TYPE_RANGES[spec.data_type]
        if not lo <= value <= hi:
            raise DriveObjectError(
                f"0x{index:04X}:{subindex:02X} {spec.name}: {value} outside {spec.data_type}",
                abort_code=0x06090030)
        key = (index, subindex)
        if key == (0x6040, 0):
            self._write_controlword(value)
            return
        if key == (0x6060, 0):
            if value not in SUPPORTED_MODES:
                raise DriveObjectError(
                    f"0x6060 Modes of operation: mode {value} not supported "
                    f"(supported: {list(SUPPORTED_MODES)})", abort_code=0x06090030)
            self._set_mode(value)
            return
        if key == (0x605A, 0) and value not in _QUICK_STOP_CODES:
            raise DriveObjectError(
                f"0x605A Quick stop option code: {value} not supported "
                f"(supported: {list(_QUICK_STOP_CODES)})", abort_code=0x06090030)
        if key == (0x605E, 0) and value not in _FAULT_REACTION_CODES:
            raise DriveObjectError(
                f"0x605E Fault reaction option code: {value} not supported "
                f"(supported: {list(_FAULT_REACTION_CODES)})", abort_code=0x06090030)
        if key == (0x6086, 0) and value != 0:
            raise DriveObjectError("0x6086 Motion profile type: only 0 (linear ramp)",
                                   abort_code=0x06090030)
        if key in ((0x607D, 1), (0x607D, 2)):
            lo_inc = value if subindex == 1 else self._od[(0x607D, 1)]
            hi_inc = value if subindex == 2 else self._od[(0x607D, 2)]
            if lo_inc >= hi_inc or lo_inc < 0 or hi_inc > _inc(self.cylinder.stroke_mm):
                raise DriveObjectError(
                    f"0x607D:{subindex:02X} software position limit {value} gives "
                    f"[{lo_inc}, {hi_inc}] outside the stroke [0, "
                    f"{_inc(self.cylinder.stroke_mm)}] or empty", abort_code=0x06090030)
        self._od[key] = value
        if key in _PARAMETER_KEYS:      # the target velocity, say, changes no parameter
            self._apply_parameters()

    def owns(self, index: int, subindex: int = 0) -> bool:
        """True if ``index:subindex`` is one of the drive's objects (see :data:`OBJECTS`)."""
        return (index, subindex) in OBJECTS

    def _spec_of(self, index: int, subindex: int) -> ObjectSpec:
        spec = OBJECTS.get((index, subindex))
        if spec is None:
            if any(i == index for i, _ in OBJECTS):
                raise DriveObjectError(f"0x{index:04X}:{subindex:02X}: no such sub-index",
                                       abort_code=0x06090011)
            raise DriveObjectError(f"0x{index:04X}:{subindex:02X}: no such object in the drive",
                                   abort_code=0x06020000)
        return spec

    def _apply_parameters(self) -> None:
        """Derive the working parameters from the objects in :data:`_PARAMETER_KEYS` (and the
        cylinder's constants)."""
        od = self._od
        cyl = self.cylinder
        self._vmax = min(_mm(od[(0x607F, 0)]), cyl.rod_speed_max_mm_per_s)
        self._v_profile = min(_mm(od[(0x6081, 0)]), self._vmax)
        self._accel = max(_mm(od[(0x6083, 0)]), 1e-6)
        self._decel = max(_mm(od[(0x6084, 0)]), 1e-6)
        self._qs_decel = max(_mm(od[(0x6085, 0)]), 1e-6)
        self._fe_window = _mm(od[(0x6065, 0)])
        self._fe_timeout_s = od[(0x6066, 0)] * 1e-3
        self._pos_window = _mm(od[(0x6067, 0)])
        self._pos_window_s = od[(0x6068, 0)] * 1e-3
        self._vel_window = _mm(od[(0x606D, 0)])
        self._vel_window_s = od[(0x606E, 0)] * 1e-3
        self._vel_threshold = _mm(od[(0x606F, 0)])
        self._vel_threshold_s = od[(0x6070, 0)] * 1e-3
        self._lim_min = _mm(od[(0x607D, 1)])
        self._lim_max = _mm(od[(0x607D, 2)])
        self._overload_limit_s = od[(0x2002, 0)] * 1e-3
        torque_limit = od[(0x6072, 0)] * 1e-3 * cyl.rated_torque_n_m
        cyl.torque_limit_n_m = min(torque_limit, cyl.torque_max_n_m)

    # ------------------------------------------------------------------ typed accessors
    @property
    def state(self) -> DriveState:
        """Present state of the power drive system."""
        return self._state

    @property
    def statusword(self) -> int:
        """0x6041 Statusword."""
        sw = STATE_BITS[self._state] | SW_REMOTE
        if self._main_power and self._state is not DriveState.NOT_READY_TO_SWITCH_ON:
            sw |= SW_VOLTAGE_ENABLED
        if self._overload_s > 0.0:
            sw |= SW_WARNING
        if self._target_reached:
            sw |= SW_TARGET_REACHED
        if self._internal_limit:
            sw |= SW_INTERNAL_LIMIT
        if self._mode == MODE_PROFILE_POSITION:
            if self._sp_ack:
                sw |= SW_OP_SPECIFIC_12
            if self._following_error:
                sw |= SW_OP_SPECIFIC_13
        elif self._mode == MODE_PROFILE_VELOCITY and self._speed_zero:
            sw |= SW_OP_SPECIFIC_12
        return sw

    @property
    def controlword(self) -> int:
        """Last 0x6040 Controlword written."""
        return self._controlword

    @property
    def mode_display(self) -> int:
        """0x6061 Modes of operation display."""
        return self._mode

    @property
    def error_code(self) -> int:
        """0x603F Error code of the present (or last unreset) fault; 0 if none."""
        return self._error_code

    @property
    def error_register(self) -> int:
        """0x1001 Error register: bit 0 generic, bit 1 current, bit 2 voltage, bit 5 profile."""
        code = self._error_code
        if code == 0:
            return 0
        reg = 0x01
        if code & 0xF000 == 0x2000:
            reg |= 0x02
        elif code & 0xF000 == 0x3000:
            reg |= 0x04
        elif code & 0xF000 == 0x8000:
            reg |= 0x20
        return reg

    @property
    def position_demand_mm(self) -> float:
        """Demand position of the trajectory generator."""
        return self._profile.position

    @property
    def following_error_mm(self) -> float:
        """Demand minus actual position."""
        return self._profile.position - self.cylinder.position_mm

    @property
    def main_power(self) -> bool:
        """Whether the power stage has its DC supply (a fault hook)."""
        return self._main_power

    @main_power.setter
    def main_power(self, on: bool) -> None:
        self._main_power = bool(on)
        if not on and self._state in POWERED_STATES:
            self._raise_fault(ErrorCode.DC_LINK_UNDER_VOLTAGE)

    def inject_fault(self, code: int = ErrorCode.GENERIC) -> None:
        """Fault hook: raise fault ``code``; it stays active until :meth:`clear_injected_fault`."""
        self._injected.add(int(code))
        self._raise_fault(int(code))

    def clear_injected_fault(self, code: int = ErrorCode.GENERIC) -> None:
        """Remove the cause of an injected fault so that a fault reset can clear it."""
        self._injected.discard(int(code))

    def pop_emcy_events(self) -> list[tuple[int, int]]:
        """Faults raised and reset since the last call, as (error code, error register) for
        EMCY: a fault as its code and register, a fault reset (transition 15) as (0, 0)."""
        events, self._emcy = self._emcy, []
        return events

    # ------------------------------------------------------------------ state machine
    def _write_controlword(self, cw: int) -> None:
        previous = self._controlword
        self._controlword = cw
        if (cw & CW_FAULT_RESET and not previous & CW_FAULT_RESET
                and self._state is DriveState.FAULT):
            self._fault_reset()
            return
        self._apply_command(decode_command(cw))
        if cw & CW_NEW_SET_POINT and not previous & CW_NEW_SET_POINT:
            self._sp_edge = True

    def _apply_command(self, command: Command) -> None:
        for state in transitions(self._state, command,
                                 quick_stop_option_code=self._od[(0x605A, 0)],
                                 main_power=self._main_power):
            self._enter(state)

    def _fault_reset(self) -> None:
        if self._injected:
            return
        if self._overload_s > self._overload_reset_fraction * self._overload_limit_s:
            return
        if not self._main_power:
            return
        self._error_code = 0
        self._following_error = False
        self._fe_time_s = 0.0
        self._emcy.append((0, 0))                 # error reset (CiA 301): no error is left
        self._enter(DriveState.SWITCH_ON_DISABLED)                          # 15

    def _enter(self, new: DriveState) -> None:
        cyl = self.cylinder
        if new is DriveState.OPERATION_ENABLED:
            self._profile.reset(cyl.position_mm, 0.0)
            self._hold_mm = cyl.position_mm
            self._active_target = None
            self._buffered_target = None
            self._last_target_mm = cyl.position_mm
            self._sp_ack = False
            self._sp_edge = False
            self._window_time_s = 0.0
            self._target_clipped = False
        elif new in (DriveState.QUICK_STOP_ACTIVE, DriveState.FAULT_REACTION_ACTIVE):
            self._profile.reset(cyl.position_mm, cyl.velocity_mm_s)
        self._state = new
        if new is not DriveState.OPERATION_ENABLED:
            self._target_reached = False
            self._sp_ack = False
            self._internal_limit = False

    def _raise_fault(self, code: int) -> None:
        if self._state in (DriveState.FAULT, DriveState.FAULT_REACTION_ACTIVE):
            return
        self._error_code = int(code)
        self._emcy.append((int(code), self.error_register))
        self._enter(DriveState.FAULT_REACTION_ACTIVE)                       # 13

    def _set_mode(self, mode: int) -> None:
        if mode == self._mode:
            return
        self._mode = mode
        cyl = self.cylinder
        self._profile.reset(cyl.position_mm, cyl.velocity_mm_s)
        self._hold_mm = cyl.position_mm
        self._active_target = None
        self._buffered_target = None
        self._last_target_mm = cyl.position_mm
        self._sp_ack = False
        self._sp_edge = False
        self._window_time_s = 0.0
        self._threshold_time_s = 0.0
        self._target_reached = False
        self._internal_limit = False

    # ------------------------------------------------------------------ cycle
    def step(self, dt: float) -> None:
        """Run one drive cycle of ``dt`` seconds and move the cylinder accordingly."""
        st = self._state
        cyl = self.cylinder
        if st is DriveState.OPERATION_ENABLED:
            mode = self._mode
            if mode == MODE_PROFILE_POSITION:
                v_cmd = self._pp_cycle(dt)
            elif mode == MODE_PROFILE_VELOCITY:
                v_cmd = self._pv_cycle(dt)
            else:
                self._profile.velocity_step(dt, 0.0, self._accel, self._decel)
                v_cmd = self._profile.velocity + self._kp_per_s * (
                    self._profile.position - cyl.position_mm)
            v_cmd = self._clamp_v(v_cmd)
            cyl.step(dt, v_cmd)
            if mode == MODE_PROFILE_POSITION:
                self._monitor_following_error(dt)
                self._monitor_position_window(dt)
            elif mode == MODE_PROFILE_VELOCITY:
                self._monitor_velocity(dt)
        elif st is DriveState.QUICK_STOP_ACTIVE or st is DriveState.FAULT_REACTION_ACTIVE:
            self._stop_cycle(dt, st)
        else:
            cyl.hold()
            self._profile.reset(cyl.position_mm, 0.0)
            if st is DriveState.NOT_READY_TO_SWITCH_ON:
                self._boot_left_s -= dt
                if self._boot_left_s <= 0.0:
                    self._enter(DriveState.SWITCH_ON_DISABLED)              # 1
        self._monitor_overload(dt)

    def pv_steady(self) -> bool:
        """Whether :meth:`step` is now the steady profile-velocity loop :meth:`run_pv_native`
        runs in C: operation enabled, mode 3, the rod not jammed."""
        return (self._state is DriveState.OPERATION_ENABLED
                and self._mode == MODE_PROFILE_VELOCITY and not self.cylinder.jammed)

    def run_pv_native(self, native: ModuleType, n: int, dt: float, dx: float, t: float,
                      x: float, next_cell: float) -> tuple[int, float, float]:
        """Up to ``n`` calls of :meth:`step` by the C twin (only while :meth:`pv_steady`).

        The twin (``native/drive_cycle_core.c``, module ``native``) runs :meth:`_pv_cycle`,
        the cylinder's step, :meth:`_monitor_velocity` and :meth:`_monitor_overload` per step,
        and the caller's sums ``t += dt``, ``x += dx``; it stops after the step in which ``x``
        reaches ``next_cell`` (the plant computes the cell, which changes the soil under the
        roller) or the overload monitor faults (raised here, as :meth:`_monitor_overload`
        raises it). Returns (steps run, t, x).
        """
        cyl = self.cylinder
        prof = self._profile
        target = self._clamp_v(0.0 if self._controlword & CW_HALT
                               else _mm(self._od[(0x60FF, 0)]))
        (done, why, t, x, prof.velocity, prof.position, self._window_time_s,
         self._threshold_time_s, self._overload_s, self._internal_limit, self._target_reached,
         self._speed_zero, cyl.position_mm, cyl.velocity_mm_s, cyl.torque_n_m, cyl.current_a,
         cyl.force_n, cyl.at_force_limit) = native.run(
            n, dt, dx, t, x, next_cell,
            target, self._lim_min, self._lim_max, self._accel, self._decel, self._vmax,
            self._vel_window, self._vel_window_s, self._vel_threshold, self._vel_threshold_s,
            self._overload_limit_s, prof.velocity, prof.position, self._window_time_s,
            self._threshold_time_s, self._overload_s,
            cyl.position_mm, cyl.velocity_mm_s, cyl.load_contact_mm,
            cyl.load_stiffness_n_per_mm, cyl.load_damping_n_s_per_mm, cyl.load_preload_n,
            cyl.m_eff_kg, cyl.k_force_n_per_n_m, cyl.velocity_gain(dt), cyl.torque_limit_n_m,
            cyl.kt_n_m_per_a, cyl.dc_bus_voltage_v, cyl.ke_v_s_per_rad, cyl.rad_per_mm,
            cyl.ra_ohm, cyl.rod_speed_max_mm_per_s, cyl.stroke_mm)
        if why & native.OVERLOAD:
            self._raise_fault(ErrorCode.CONTINUOUS_OVER_CURRENT)
        return done, t, x

    def _clamp_v(self, v: float) -> float:
        vmax = self._vmax
        if v > vmax:
            return vmax
        if v < -vmax:
            return -vmax
        return v

    def _pp_cycle(self, dt: float) -> float:
        cw = self._controlword
        if self._sp_edge:
            self._sp_edge = False
            self._latch_set_point(cw)
        elif self._sp_ack and not cw & CW_NEW_SET_POINT and self._buffered_target is None:
            self._sp_ack = False
        prof = self._profile
        if cw & CW_HALT:
            prof.velocity_step(dt, 0.0, self._accel, self._decel)
        elif self._active_target is not None:
            if prof.move_step(dt, self._active_target, self._v_profile, self._accel,
                              self._decel):
                self._active_target = self._buffered_target
                self._buffered_target = None
        else:
            prof.velocity_step(dt, 0.0, self._accel, self._decel)
        return prof.velocity + self._kp_per_s * (prof.position - self.cylinder.position_mm)

    def _latch_set_point(self, cw: int) -> None:
        immediate = bool(cw & CW_CHANGE_SET_IMMEDIATELY)
        if not immediate and self._active_target is not None and self._buffered_target is not None:
            return   # buffer full: the master must wait for set-point acknowledge to drop
        value = _mm(self._od[(0x607A, 0)])
        target = self._last_target_mm + value if cw & CW_RELATIVE else value
        clipped = min(max(target, self._lim_min), self._lim_max)
        self._target_clipped = clipped != target
        self._internal_limit = self._target_clipped
        self._last_target_mm = clipped
        if immediate or self._active_target is None:
            self._active_target = clipped
            self._buffered_target = None
        else:
            self._buffered_target = clipped
        self._sp_ack = True
        self._target_reached = False
        self._window_time_s = 0.0

    def _pv_cycle(self, dt: float) -> float:
        # (run_pv_native's C twin has this cycle and the two monitors expression for
        # expression: change both)
        cyl = self.cylinder
        target = 0.0 if self._controlword & CW_HALT else _mm(self._od[(0x60FF, 0)])
        target = self._clamp_v(target)
        limited = False
        x = cyl.position_mm
        if target > 0.0:
            room = self._lim_max - x
            v_allow = math.sqrt(2.0 * self._decel * room) if room > 0.0 else 0.0
            if target > v_allow:
                target = v_allow
                limited = True
        elif target < 0.0:
            room = x - self._lim_min
            v_allow = math.sqrt(2.0 * self._decel * room) if room > 0.0 else 0.0
            if -target > v_allow:
                target = -v_allow
                limited = True
        self._internal_limit = limited
        prof = self._profile
        prof.velocity_step(dt, target, self._accel, self._decel)
        prof.position = x
        return prof.velocity

    def _stop_cycle(self, dt: float, st: DriveState) -> None:
        cyl = self.cylinder
        prof = self._profile
        if st is DriveState.QUICK_STOP_ACTIVE:
            code = self._od[(0x605A, 0)]
            decel = self._decel if code in (1, 5) else self._qs_decel
        else:
            code = self._od[(0x605E, 0)]
            if code == 0:
                cyl.hold()
                self._enter(DriveState.FAULT)                               # 14
                return
            decel = self._decel if code == 1 else self._qs_decel
        if prof.velocity != 0.0:
            prof.velocity_step(dt, 0.0, decel, decel)
            cyl.step(dt, self._clamp_v(prof.velocity))
            if prof.velocity == 0.0:
                self._hold_mm = cyl.position_mm
            return
        if st is DriveState.FAULT_REACTION_ACTIVE:
            cyl.hold()
            self._enter(DriveState.FAULT)                                   # 14
        elif code in (1, 2):
            cyl.hold()
            self._enter(DriveState.SWITCH_ON_DISABLED)                      # 12
        else:
            cyl.step(dt, self._clamp_v(self._kp_per_s * (self._hold_mm - cyl.position_mm)))
            prof.position = self._hold_mm
            self._target_reached = abs(cyl.velocity_mm_s) < self._vel_threshold

    # ------------------------------------------------------------------ monitoring
    def _monitor_following_error(self, dt: float) -> None:
        err = self._profile.position - self.cylinder.position_mm
        if err > self._fe_window or err < -self._fe_window:
            self._fe_time_s += dt
            if self._fe_time_s >= self._fe_timeout_s:
                self._following_error = True
                self._raise_fault(ErrorCode.FOLLOWING_ERROR)
        else:
            self._fe_time_s = 0.0
            self._following_error = False

    def _monitor_position_window(self, dt: float) -> None:
        if self._state is not DriveState.OPERATION_ENABLED:
            return
        cyl = self.cylinder
        if self._controlword & CW_HALT:
            self._target_reached = self._profile.velocity == 0.0
            return
        if self._active_target is None:
            err = self._last_target_mm - cyl.position_mm
            if -self._pos_window <= err <= self._pos_window:
                self._window_time_s += dt
                self._target_reached = self._window_time_s >= self._pos_window_s
                return
        self._window_time_s = 0.0
        self._target_reached = False

    def _monitor_velocity(self, dt: float) -> None:
        if self._state is not DriveState.OPERATION_ENABLED:
            return
        v = self.cylinder.velocity_mm_s
        halted = self._controlword & CW_HALT
        target = 0.0 if halted else self._clamp_v(_mm(self._od[(0x60FF, 0)]))
        if abs(target - v) <= self._vel_window:
            self._window_time_s += dt
            self._target_reached = self._window_time_s >= self._vel_window_s
        else:
            self._window_time_s = 0.0
            self._target_reached = False
        if abs(v) <= self._vel_threshold:
            self._threshold_time_s += dt
            self._speed_zero = self._threshold_time_s >= self._vel_threshold_s
        else:
            self._threshold_time_s = 0.0
            self._speed_zero = False

    def _monitor_overload(self, dt: float) -> None:
        if self.cylinder.at_force_limit:
            self._overload_s += dt
            if self._overload_s >= self._overload_limit_s:
                self._raise_fault(ErrorCode.CONTINUOUS_OVER_CURRENT)
        elif self._overload_s > 0.0:
            self._overload_s = max(0.0, self._overload_s - dt)


def _round_u(value: float) -> int:
    return round(value)


def _torque_permille(drive: Cia402Drive) -> int:
    cyl = drive.cylinder
    return clip_to_type(round(1000.0 * cyl.torque_n_m / cyl.rated_torque_n_m), "I16")


def _current_permille(drive: Cia402Drive) -> int:
    cyl = drive.cylinder
    return clip_to_type(round(1000.0 * cyl.current_a / cyl.rated_current_a), "I16")


#: the objects :meth:`Cia402Drive._apply_parameters` reads: writing any other object leaves
#: the derived parameters as they are, so it is not re-run then (a test checks this set)
_PARAMETER_KEYS = frozenset({
    (0x607F, 0), (0x6081, 0), (0x6083, 0), (0x6084, 0), (0x6085, 0), (0x6065, 0), (0x6066, 0),
    (0x6067, 0), (0x6068, 0), (0x606D, 0), (0x606E, 0), (0x606F, 0), (0x6070, 0), (0x607D, 1),
    (0x607D, 2), (0x2002, 0), (0x6072, 0)})

_COMPUTED = {
    (0x1001, 0): lambda d: d.error_register,
    (0x2001, 0): lambda d: clip_to_type(round(d.cylinder.force_n), "I32"),
    (0x603F, 0): lambda d: d.error_code,
    (0x6040, 0): lambda d: d.controlword,
    (0x6041, 0): lambda d: d.statusword,
    (0x6060, 0): lambda d: d.mode_display,
    (0x6061, 0): lambda d: d.mode_display,
    (0x6062, 0): lambda d: _inc(d.position_demand_mm),
    (0x6064, 0): lambda d: _inc(d.cylinder.position_mm),
    (0x606B, 0): lambda d: _inc(d._profile.velocity),
    (0x606C, 0): lambda d: _inc(d.cylinder.velocity_mm_s),
    (0x6077, 0): _torque_permille,
    (0x6078, 0): _current_permille,
    (0x6079, 0): lambda d: round(1000.0 * d.cylinder.dc_bus_voltage_v) if d.main_power else 0,
    (0x60F4, 0): lambda d: _inc(d.following_error_mm),
}
