"""CiA 402 drive logic: state machine, statusword, pp and pv modes, monitoring, object access."""

from __future__ import annotations

import dataclasses
import itertools

import pytest
from canopen.profiles.p402 import State402

from plant_emulators.sowing_depth.cia402 import (
    OBJECTS,
    Cia402Drive,
    Command,
    DriveObjectError,
    DriveState,
    ErrorCode,
    decode_command,
)
from plant_emulators.sowing_depth.cia402_states import transitions
from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.cylinder import ServoCylinder

S = DriveState
DT = 0.001


def make_drive(**drive_overrides: object) -> Cia402Drive:
    cfg = load_rig_config()
    drive_cfg = dataclasses.replace(cfg.drive, **drive_overrides)
    drive = Cia402Drive(drive_cfg, ServoCylinder(cfg.motor, cfg.cylinder))
    run(drive, drive_cfg.boot_time_ms * 1e-3 + DT)
    return drive


def run(drive: Cia402Drive, seconds: float) -> None:
    for _ in range(round(seconds / DT)):
        drive.step(DT)


def cw(drive: Cia402Drive, *words: int) -> None:
    for word in words:
        drive.write(0x6040, 0, word)


def enabled(mode: int = 1, **overrides: object) -> Cia402Drive:
    drive = make_drive(**overrides)
    drive.write(0x6060, 0, mode)
    cw(drive, 0x06, 0x07, 0x0F)
    assert drive.state is S.OPERATION_ENABLED
    return drive


def bring_to(state: DriveState, **overrides: object) -> Cia402Drive:
    drive = make_drive(**overrides)
    path = {
        S.SWITCH_ON_DISABLED: (),
        S.READY_TO_SWITCH_ON: (0x06,),
        S.SWITCHED_ON: (0x06, 0x07),
        S.OPERATION_ENABLED: (0x06, 0x07, 0x0F),
        S.QUICK_STOP_ACTIVE: (0x06, 0x07, 0x0F, 0x02),
    }
    if state is S.FAULT:
        cw(drive, 0x06, 0x07, 0x0F)
        drive.inject_fault(ErrorCode.GENERIC)
        run(drive, 0.01)
        drive.clear_injected_fault(ErrorCode.GENERIC)
    else:
        cw(drive, *path[state])
    assert drive.state is state
    return drive


# ---------------------------------------------------------------------- command decoding
@pytest.mark.parametrize(("word", "command"), [
    (0x0006, Command.SHUTDOWN), (0x0086, Command.SHUTDOWN), (0x000E, Command.SHUTDOWN),
    (0x0007, Command.SWITCH_ON), (0x000F, Command.ENABLE_OPERATION),
    (0x001F, Command.ENABLE_OPERATION), (0x0000, Command.DISABLE_VOLTAGE),
    (0x0001, Command.DISABLE_VOLTAGE), (0x000D, Command.DISABLE_VOLTAGE),
    (0x0002, Command.QUICK_STOP), (0x000B, Command.QUICK_STOP),
])
def test_controlword_commands_decode_per_cia402(word: int, command: Command) -> None:
    assert decode_command(word) is command


# ---------------------------------------------------------------------- state diagram
AUTOMATIC = {("NOT READY TO SWITCH ON", "SWITCH ON DISABLED"), ("START", "NOT READY TO SWITCH ON"),
             ("FAULT REACTION ACTIVE", "FAULT"), ("FAULT", "SWITCH ON DISABLED")}


@pytest.mark.parametrize(("pair", "word"), sorted(
    (pair, word) for pair, word in State402.TRANSITIONTABLE.items() if pair not in AUTOMATIC))
def test_transition_table_agrees_with_canopens_master(pair: tuple[str, str], word: int) -> None:
    """Every controlword canopen's BaseNode402 sends moves our state machine as it expects.

    (Its automatic and fault-reset entries are exercised by the tests below.)
    """
    start, end = pair
    path = transitions(DriveState(start), decode_command(word), quick_stop_option_code=6)
    assert path and path[-1] is DriveState(end)


def test_power_on_is_not_ready_then_switch_on_disabled_after_boot() -> None:   # 0, 1
    cfg = load_rig_config()
    drive = Cia402Drive(cfg.drive, ServoCylinder(cfg.motor, cfg.cylinder))
    assert drive.state is S.NOT_READY_TO_SWITCH_ON
    cw(drive, 0x06)                      # ignored while not ready
    run(drive, cfg.drive.boot_time_ms * 1e-3 - 2 * DT)
    assert drive.state is S.NOT_READY_TO_SWITCH_ON
    run(drive, 3 * DT)
    assert drive.state is S.SWITCH_ON_DISABLED


@pytest.mark.parametrize(("start", "words", "end", "transition"), [
    (S.SWITCH_ON_DISABLED, (0x06,), S.READY_TO_SWITCH_ON, 2),
    (S.READY_TO_SWITCH_ON, (0x07,), S.SWITCHED_ON, 3),
    (S.READY_TO_SWITCH_ON, (0x0F,), S.OPERATION_ENABLED, "3+4"),
    (S.SWITCHED_ON, (0x0F,), S.OPERATION_ENABLED, 4),
    (S.OPERATION_ENABLED, (0x07,), S.SWITCHED_ON, 5),
    (S.SWITCHED_ON, (0x06,), S.READY_TO_SWITCH_ON, 6),
    (S.READY_TO_SWITCH_ON, (0x00,), S.SWITCH_ON_DISABLED, 7),
    (S.READY_TO_SWITCH_ON, (0x02,), S.SWITCH_ON_DISABLED, "7 (quick stop)"),
    (S.OPERATION_ENABLED, (0x06,), S.READY_TO_SWITCH_ON, 8),
    (S.OPERATION_ENABLED, (0x00,), S.SWITCH_ON_DISABLED, 9),
    (S.SWITCHED_ON, (0x00,), S.SWITCH_ON_DISABLED, 10),
    (S.SWITCHED_ON, (0x02,), S.SWITCH_ON_DISABLED, "10 (quick stop)"),
    (S.OPERATION_ENABLED, (0x02,), S.QUICK_STOP_ACTIVE, 11),
    (S.QUICK_STOP_ACTIVE, (0x00,), S.SWITCH_ON_DISABLED, 12),
    (S.FAULT, (0x00, 0x80), S.SWITCH_ON_DISABLED, 15),
    (S.QUICK_STOP_ACTIVE, (0x0F,), S.OPERATION_ENABLED, 16),
    # Commands that are not transitions from the state leave it unchanged.
    (S.SWITCH_ON_DISABLED, (0x07,), S.SWITCH_ON_DISABLED, None),
    (S.SWITCH_ON_DISABLED, (0x0F,), S.SWITCH_ON_DISABLED, None),
    (S.READY_TO_SWITCH_ON, (0x06,), S.READY_TO_SWITCH_ON, None),
    (S.OPERATION_ENABLED, (0x0F,), S.OPERATION_ENABLED, None),
    (S.FAULT, (0x06, 0x07, 0x0F), S.FAULT, None),
    (S.QUICK_STOP_ACTIVE, (0x06,), S.QUICK_STOP_ACTIVE, None),
])
def test_transitions_of_the_state_diagram(start: DriveState, words: tuple[int, ...],
                                          end: DriveState, transition: object) -> None:
    drive = bring_to(start, quick_stop_option_code=6)
    cw(drive, *words)
    assert drive.state is end, f"transition {transition}"


def test_transition_16_needs_a_quick_stop_option_that_stays() -> None:
    drive = bring_to(S.QUICK_STOP_ACTIVE, quick_stop_option_code=2)
    cw(drive, 0x0F)
    assert drive.state is S.QUICK_STOP_ACTIVE
    run(drive, 0.01)                                    # standstill reached → 12
    assert drive.state is S.SWITCH_ON_DISABLED


@pytest.mark.parametrize("state", [S.SWITCH_ON_DISABLED, S.READY_TO_SWITCH_ON, S.SWITCHED_ON,
                                   S.OPERATION_ENABLED, S.QUICK_STOP_ACTIVE])
def test_fault_from_any_state_goes_through_fault_reaction_to_fault(state: DriveState) -> None:
    drive = bring_to(state, quick_stop_option_code=6)
    drive.inject_fault(ErrorCode.GENERIC)                                # 13
    assert drive.state is S.FAULT_REACTION_ACTIVE
    run(drive, 0.1)                                                      # 14
    assert drive.state is S.FAULT
    assert drive.error_code == ErrorCode.GENERIC
    cw(drive, 0x00, 0x80)
    assert drive.state is S.FAULT, "reset refused while the injected cause is active"
    drive.clear_injected_fault(ErrorCode.GENERIC)
    cw(drive, 0x00, 0x80)                                                # 15
    assert drive.state is S.SWITCH_ON_DISABLED
    assert drive.error_code == 0


def test_fault_reset_needs_a_rising_edge() -> None:
    drive = bring_to(S.FAULT)
    cw(drive, 0x80)                   # bit 7 was low: rising edge
    assert drive.state is S.SWITCH_ON_DISABLED
    drive.inject_fault()
    run(drive, 0.1)
    drive.clear_injected_fault()
    cw(drive, 0x80)                   # bit 7 still high: no edge
    assert drive.state is S.FAULT
    cw(drive, 0x00, 0x80)
    assert drive.state is S.SWITCH_ON_DISABLED


def test_fault_reset_bit_outside_fault_does_not_swallow_the_command() -> None:
    drive = bring_to(S.SWITCH_ON_DISABLED)
    cw(drive, 0x86)
    assert drive.state is S.READY_TO_SWITCH_ON


# ---------------------------------------------------------------------- statusword
@pytest.mark.parametrize(("state", "expected"), [
    (S.SWITCH_ON_DISABLED, 0x0250), (S.READY_TO_SWITCH_ON, 0x0231), (S.SWITCHED_ON, 0x0233),
    (S.QUICK_STOP_ACTIVE, 0x0217), (S.FAULT, 0x0218),
])
def test_statusword_values_per_state(state: DriveState, expected: int) -> None:
    drive = bring_to(state, quick_stop_option_code=6)
    if state is S.QUICK_STOP_ACTIVE:
        run(drive, 0.001)
        assert drive.statusword & ~0x0400 == expected   # target reached may be set when held
    else:
        assert drive.statusword == expected
    mask, value = State402.SW_MASK[state.value]
    assert drive.read(0x6041, 0) & mask == value


def test_statusword_in_operation_enabled_and_fault_reaction() -> None:
    drive = bring_to(S.OPERATION_ENABLED)
    assert drive.statusword & 0x6F == 0x27
    assert drive.statusword & 0x0200, "remote"
    assert drive.statusword & 0x0010, "voltage enabled"
    drive.inject_fault()
    assert drive.statusword & 0x4F == 0x0F
    assert drive.statusword & 0x0008


def test_main_power_drives_voltage_enabled_and_faults_a_powered_drive() -> None:
    drive = bring_to(S.READY_TO_SWITCH_ON)
    drive.main_power = False
    assert not drive.statusword & 0x0010
    cw(drive, 0x07)
    assert drive.state is S.READY_TO_SWITCH_ON, "no switch-on without main power"
    drive.main_power = True
    cw(drive, 0x0F)
    drive.main_power = False
    run(drive, 0.1)
    assert drive.state is S.FAULT
    assert drive.error_code == ErrorCode.DC_LINK_UNDER_VOLTAGE
    assert drive.error_register & 0x05 == 0x05
    cw(drive, 0x00, 0x80)
    assert drive.state is S.FAULT
    drive.main_power = True
    cw(drive, 0x00, 0x80)
    assert drive.state is S.SWITCH_ON_DISABLED


# ---------------------------------------------------------------------- profile position
def move(drive: Cia402Drive, target_mm: float, control: int = 0x0F) -> None:
    drive.write(0x607A, 0, round(target_mm * 100))
    cw(drive, control | 0x10)
    drive.step(DT)
    cw(drive, control)


def run_until_target_reached(drive: Cia402Drive, limit_s: float = 10.0) -> tuple[float, float]:
    """Step until statusword bit 10; return (time, peak |velocity|)."""
    t, peak = 0.0, 0.0
    while not drive.statusword & 0x0400:
        drive.step(DT)
        t += DT
        peak = max(peak, abs(drive.cylinder.velocity_mm_s))
        assert t < limit_s, "target never reached"
    return t, peak


def test_pp_new_set_point_handshake_and_target_reached() -> None:
    drive = enabled(mode=1)
    run(drive, 0.02)
    assert drive.statusword & 0x0400, "at rest on its position: target reached"
    drive.write(0x607A, 0, 6000)
    cw(drive, 0x1F)
    assert not drive.statusword & 0x1000, "set-point is taken at the next cycle"
    drive.step(DT)
    assert drive.statusword & 0x1000, "set-point acknowledge"
    assert not drive.statusword & 0x0400
    cw(drive, 0x0F)
    drive.step(DT)
    assert not drive.statusword & 0x1000, "acknowledge drops with bit 4"
    t, peak = run_until_target_reached(drive)
    assert abs(drive.read(0x6064, 0) - 6000) <= drive.read(0x6067, 0)
    assert peak <= 50.0 + 1e-9
    # 20 mm at 50 mm/s with 250 mm/s² ramps: 0.2 s + 0.2 s + 0.2 s cruise, plus settling.
    assert 0.55 < t < 0.75
    assert drive.mode_display == 1 and drive.read(0x6061, 0) == 1


def test_pp_profile_respects_profile_velocity_and_acceleration() -> None:
    drive = enabled(mode=1)
    drive.write(0x6081, 0, 2000)          # 20 mm/s
    drive.write(0x6083, 0, 10000)         # 100 mm/s²
    move(drive, 60.0)
    velocities = []
    while not drive.statusword & 0x0400:
        drive.step(DT)
        velocities.append(drive.read(0x606B, 0) / 100.0)
    assert max(velocities) == pytest.approx(20.0, abs=1e-6)
    accel = max(b - a for a, b in itertools.pairwise(velocities)) / DT
    assert accel == pytest.approx(100.0, rel=0.01)


def test_pp_change_set_immediately_retargets_during_a_move() -> None:
    drive = enabled(mode=1)
    move(drive, 90.0)
    run(drive, 0.4)
    assert drive.cylinder.position_mm > 45.0
    move(drive, 20.0, control=0x2F)       # bit 5: change set immediately
    run_until_target_reached(drive)
    assert drive.cylinder.position_mm == pytest.approx(20.0, abs=0.1)
    assert drive.state is S.OPERATION_ENABLED


def test_pp_buffered_set_point_runs_after_the_current_one() -> None:
    drive = enabled(mode=1)
    move(drive, 60.0)
    run(drive, 0.1)
    move(drive, 20.0)                     # bit 5 = 0: buffered
    drive.step(DT)
    assert drive.statusword & 0x1000, "acknowledge stays while the buffer is full"
    peak = 0.0
    while not drive.statusword & 0x0400:
        drive.step(DT)
        peak = max(peak, drive.cylinder.position_mm)
    assert peak == pytest.approx(60.0, abs=0.2), "the first target was reached first"
    assert drive.cylinder.position_mm == pytest.approx(20.0, abs=0.1)
    assert not drive.statusword & 0x1000


def test_pp_relative_set_point_adds_to_the_previous_target() -> None:
    drive = enabled(mode=1)
    move(drive, 30.0)
    run_until_target_reached(drive)
    drive.write(0x607A, 0, 1000)
    cw(drive, 0x5F)                       # bit 6 relative
    drive.step(DT)
    cw(drive, 0x4F)
    run_until_target_reached(drive)
    assert drive.cylinder.position_mm == pytest.approx(40.0, abs=0.1)


def test_pp_halt_stops_and_release_resumes() -> None:
    drive = enabled(mode=1)
    move(drive, 80.0)
    run(drive, 0.3)
    cw(drive, 0x010F)                     # halt
    run(drive, 0.5)
    held = drive.cylinder.position_mm
    assert drive.read(0x606B, 0) == 0, "demand velocity"
    assert drive.cylinder.velocity_mm_s == pytest.approx(0.0, abs=0.01)
    assert drive.statusword & 0x0400, "target reached signals the halt is complete"
    assert held < 79.0
    cw(drive, 0x000F)
    drive.step(DT)
    assert not drive.statusword & 0x0400
    run_until_target_reached(drive)
    assert drive.cylinder.position_mm == pytest.approx(80.0, abs=0.1)


def test_pp_target_outside_software_limits_is_clipped() -> None:
    drive = enabled(mode=1)
    move(drive, 100.0)
    drive.step(DT)
    assert drive.statusword & 0x0800, "internal limit active"
    run_until_target_reached(drive)
    assert drive.cylinder.position_mm == pytest.approx(99.0, abs=0.1)
    move(drive, -5.0)
    run_until_target_reached(drive)
    assert drive.cylinder.position_mm == pytest.approx(1.0, abs=0.1)


# ---------------------------------------------------------------------- profile velocity
def test_pv_ramps_to_target_velocity_and_reports_target_reached() -> None:
    drive = enabled(mode=3)
    drive.write(0x60FF, 0, 2000)          # 20 mm/s
    run(drive, 0.04)
    assert 0.0 < drive.cylinder.velocity_mm_s < 20.0
    run(drive, 0.1)
    assert drive.cylinder.velocity_mm_s == pytest.approx(20.0, abs=0.05)
    assert drive.statusword & 0x0400
    assert not drive.statusword & 0x1000, "speed is not zero"
    assert drive.read(0x606C, 0) == pytest.approx(2000, abs=5)
    drive.write(0x60FF, 0, 0)
    run(drive, 0.2)
    assert drive.statusword & 0x1000, "speed = 0"


def test_pv_clamps_to_the_rod_speed_limit_and_stops_at_the_software_limit() -> None:
    drive = enabled(mode=3)
    drive.write(0x60FF, 0, 10000)         # 100 mm/s asked
    peak, limited = 0.0, False
    for _ in range(3000):
        drive.step(DT)
        peak = max(peak, drive.cylinder.velocity_mm_s)
        limited |= bool(drive.statusword & 0x0800)
    assert peak <= 50.0 + 1e-9
    assert limited
    assert drive.cylinder.position_mm <= 99.0 + 0.3
    assert drive.cylinder.velocity_mm_s == pytest.approx(0.0, abs=1e-3)
    drive.write(0x60FF, 0, -3000)
    run(drive, 0.5)
    assert drive.cylinder.velocity_mm_s == pytest.approx(-30.0, abs=0.1)


def test_pv_halt_decelerates_to_zero() -> None:
    drive = enabled(mode=3)
    drive.write(0x60FF, 0, 3000)
    run(drive, 0.3)
    cw(drive, 0x010F)
    run(drive, 0.2)
    assert drive.cylinder.velocity_mm_s == pytest.approx(0.0, abs=1e-3)


def test_mode_switch_is_displayed_and_holds_position() -> None:
    drive = enabled(mode=3)
    drive.write(0x60FF, 0, 2000)
    run(drive, 0.2)
    drive.write(0x6060, 0, 1)
    assert drive.read(0x6061, 0) == 1
    run(drive, 0.5)
    assert drive.cylinder.velocity_mm_s == pytest.approx(0.0, abs=1e-3)
    assert drive.state is S.OPERATION_ENABLED


# ---------------------------------------------------------------------- quick stop
def test_quick_stop_decelerates_on_the_quick_stop_ramp_then_disables() -> None:
    drive = enabled(mode=3, quick_stop_option_code=2)
    drive.write(0x60FF, 0, 5000)
    run(drive, 0.4)
    assert drive.cylinder.velocity_mm_s == pytest.approx(50.0, abs=0.1)
    cw(drive, 0x02)
    assert drive.state is S.QUICK_STOP_ACTIVE
    t = 0.0
    while drive.state is S.QUICK_STOP_ACTIVE:
        drive.step(DT)
        t += DT
    assert drive.state is S.SWITCH_ON_DISABLED
    assert t == pytest.approx(0.05, abs=0.005)          # 50 mm/s at 1000 mm/s²


def test_quick_stop_option_6_holds_in_quick_stop_active() -> None:
    drive = enabled(mode=3, quick_stop_option_code=6)
    drive.write(0x60FF, 0, 3000)
    run(drive, 0.3)
    cw(drive, 0x02)
    run(drive, 0.5)
    assert drive.state is S.QUICK_STOP_ACTIVE
    assert drive.cylinder.velocity_mm_s == pytest.approx(0.0, abs=1e-3)
    assert drive.statusword & 0x0400


# ---------------------------------------------------------------------- monitoring faults
def test_following_error_faults_the_drive_and_reset_clears_it_when_gone() -> None:
    drive = enabled(mode=1)
    drive.cylinder.jammed = True
    move(drive, 80.0)
    t = 0.0
    while drive.state is S.OPERATION_ENABLED:
        drive.step(DT)
        t += DT
        assert t < 1.0
    assert drive.statusword & 0x2000, "following error bit 13"
    assert drive.state is S.FAULT_REACTION_ACTIVE
    assert drive.error_code == ErrorCode.FOLLOWING_ERROR
    assert drive.error_register == 0x21
    assert drive.pop_emcy_events() == [(0x8611, 0x21)]
    assert drive.pop_emcy_events() == []
    run(drive, 0.1)
    assert drive.state is S.FAULT
    drive.cylinder.jammed = False
    cw(drive, 0x00, 0x80)
    assert drive.state is S.SWITCH_ON_DISABLED
    assert not drive.statusword & 0x2000
    # the fault reset is an EMCY event too: error code 0x0000, nothing left in 0x1001 (CiA 301)
    assert drive.pop_emcy_events() == [(0x0000, 0x00)]
    assert drive.error_register == 0
    cw(drive, 0x06, 0x07, 0x0F)
    move(drive, 50.0)
    run_until_target_reached(drive)
    assert drive.cylinder.position_mm == pytest.approx(50.0, abs=0.1)


def test_force_limit_exceeded_too_long_is_an_overcurrent_fault() -> None:
    drive = enabled(mode=1, following_error_window_mm=1e6)
    cyl = drive.cylinder
    cyl.load_contact_mm = 45.0
    cyl.load_stiffness_n_per_mm = 2000.0  # 10 kN reached 5 mm past contact
    move(drive, 90.0)
    peak_force, limit_seen, t_limit = 0.0, False, None
    t = 0.0
    while drive.state is S.OPERATION_ENABLED:
        drive.step(DT)
        t += DT
        peak_force = max(peak_force, abs(cyl.force_n))
        if cyl.at_force_limit and t_limit is None:
            t_limit = t
            limit_seen = True
            assert drive.statusword & 0x0080, "warning while at the force limit"
        assert t < 3.0
    assert limit_seen and t_limit is not None
    assert t - t_limit == pytest.approx(0.5, abs=0.01)
    assert peak_force <= 9806.65 + 1e-6
    assert drive.error_code == ErrorCode.CONTINUOUS_OVER_CURRENT
    assert drive.error_register == 0x03
    run(drive, 0.2)                       # quick-stop ramp from the stalled rod
    assert drive.state is S.FAULT
    cw(drive, 0x00, 0x80)
    assert drive.state is S.FAULT, "not cooled down yet"
    run(drive, 0.3)
    cw(drive, 0x00, 0x80)
    assert drive.state is S.SWITCH_ON_DISABLED


def test_max_torque_object_lowers_the_force_limit() -> None:
    drive = enabled(mode=1, following_error_window_mm=1e6)
    drive.write(0x6072, 0, drive.read(0x6072, 0) // 2)
    cyl = drive.cylinder
    cyl.load_contact_mm = 45.0
    cyl.load_stiffness_n_per_mm = 2000.0
    move(drive, 90.0)
    peak = 0.0
    for _ in range(400):
        drive.step(DT)
        peak = max(peak, cyl.force_n)
    assert peak == pytest.approx(9806.65 / 2, rel=0.01)


# ---------------------------------------------------------------------- object access
def test_every_object_reads_within_its_data_type() -> None:
    drive = enabled(mode=1)
    ranges = {"U8": (0, 255), "I8": (-128, 127), "U16": (0, 65535), "I16": (-32768, 32767),
              "U32": (0, 2**32 - 1), "I32": (-(2**31), 2**31 - 1)}
    for (index, sub), spec in OBJECTS.items():
        value = drive.read(index, sub)
        lo, hi = ranges[spec.data_type]
        assert isinstance(value, int) and lo <= value <= hi, spec.name


@pytest.mark.parametrize(("index", "sub", "value", "code"), [
    (0x6099, 0, 1, 0x06020000),            # no such object
    (0x607D, 3, 1, 0x06090011),            # no such sub-index
    (0x6041, 0, 1, 0x06010002),            # read-only
    (0x6502, 0, 1, 0x06010002),            # constant
    (0x6040, 0, 0x10000, 0x06090030),      # outside UNSIGNED16
    (0x6060, 0, 6, 0x06090030),            # homing not supported
    (0x605A, 0, 3, 0x06090030),            # option code not implemented
    (0x607D, 1, 9900, 0x06090030),         # min >= max
    (0x607D, 2, 20000, 0x06090030),        # beyond the stroke
    (0x6086, 0, 3, 0x06090030),            # only linear ramps
])
def test_refused_writes_carry_the_sdo_abort_code(index: int, sub: int, value: int,
                                                 code: int) -> None:
    drive = make_drive()
    with pytest.raises(DriveObjectError) as info:
        drive.write(index, sub, value)
    assert info.value.abort_code == code
    assert f"0x{index:04X}" in str(info.value)


def test_unknown_objects_are_refused_on_read() -> None:
    drive = make_drive()
    with pytest.raises(DriveObjectError) as info:
        drive.read(0x1000, 0)                # the CANopen node's, not the drive's
    assert info.value.abort_code == 0x06020000
    assert not drive.owns(0x1000) and drive.owns(0x6041)


def test_units_of_position_velocity_and_parameters() -> None:
    drive = enabled(mode=3)
    assert drive.read(0x60A8, 0) == 0xFB010000
    assert drive.read(0x60A9, 0) == 0xFB010300
    assert drive.read(0x6064, 0) == 4000          # 40.00 mm at power-on
    assert drive.read(0x6081, 0) == 5000          # 50 mm/s
    assert drive.read(0x607D, 1) == 100 and drive.read(0x607D, 2) == 9900
    assert drive.read(0x6502, 0) == 0b101
