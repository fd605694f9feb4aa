"""The reference depth controller built against another database (the DepthPro DP-200 of
docs/examples/byo-depth): bound to the rig by its binding, it controls as the reference does on
agrihil's own database, to the last digit in lockstep, and remaps the drive's PDOs at boot.

The DP-200's layout differs from the rig's DBC in ids and node id (11-bit CANopen-style frames,
node 0x0A, instead of 29-bit J1939 frames at source address 0x80 and node 1), byte order (big
endian), units and scalings (depth in cm by 0.01, inclinometer in V by 0.001, roller travel in
µm), one multiplexed sensor hub frame for the inclinometer and the draw-wire sensor, status
enums with other numbers, a 3-bit alive counter and other cycle times (status every 200 ms,
heartbeat every 500 ms). Its scalings are exact multiples of the rig's resolutions, so every
value reaches the law as the same float. Its drive PDOs are its own: RPDO1 at 0x302 (target
velocity, controlword), TPDO1 at 0x1A2 (position, statusword, mode display), TPDO3 at 0x2A2
event-driven, configured by SDO at boot.
"""

from __future__ import annotations

import dataclasses
import re
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cantools
import numpy as np
import pytest

from hil.dut.inprocess import Controller, InProcessDut
from hil.record import load_traces
from hil.rig.runner import RunOptions, run_scenario
from hil.rig.scenario import Event
from plant_emulators.sowing_depth.rig import SowingDepthRig
from reference_controllers.inprocess import sowing_depth_dp200, sowing_depth_fuzzy_pid
from reference_controllers.sowing_depth.dbc_adapter import (
    DP200_DATABASE,
    DP200_SIGNALS,
    DbcDepthController,
    dp200,
)
from reference_controllers.sowing_depth.drive_config import PdoConfig, check_against_database
from tests.helpers.same_measurements import qualified_measurements

REPO = Path(__file__).resolve().parents[2]
HIL = str(Path(sys.executable).with_name("hil"))
EXAMPLE = REPO / "docs" / "examples" / "byo-depth"
BINDING = EXAMPLE / "depthpro_dp200.binding.toml"
PROFILE = EXAMPLE / "depthpro-dp200-daemon.toml"
REFERENCE = REPO / "dut_profiles" / "sowing-depth-fuzzy-pid-daemon.toml"
PARAMS: dict[str, Any] = {"kp0": 3.0, "ki0": 0.1, "kd0": 0.0}
DP200_RIG = {"wiring": {"binding_file": str(BINDING)}}


def _scenario() -> Any:
    """6 s through the paths that matter: boot and the drive's configuration, a set-point
    step, a broken inclinometer wire (the roller hold), the controller's power cycle."""
    base = SowingDepthRig.load_scenario("depth-step")
    return dataclasses.replace(base, duration_s=6.0, events=(
        Event(at_s=1.0, set={"target_depth_mm": 40.0}),
        Event(at_s=3.0, fault="inclinometer_open_circuit"),
        Event(at_s=3.6, clear="inclinometer_open_circuit"),
        Event(at_s=4.5, dut="restart")))


def _run(tmp: Path, make: Callable[[], Controller], rig: dict[str, Any],
         scenario: Any = None) -> tuple[Controller, dict[str, np.ndarray]]:
    dut = InProcessDut(make(), factory=make)
    result = run_scenario(SowingDepthRig, scenario or _scenario(), dut,
                          RunOptions(out_dir=tmp, bus="inline", clock="lockstep",
                                     rig_config=rig))
    assert result.record["verdict"] != "error", result.record.get("error")
    return dut.controller, load_traces(tmp / "traces.npz")[0]


def _bus(tmp: Path) -> list[tuple[float, int, bytes, str]]:
    """(time, id, data, T/R) of every frame of the run's bus.log."""
    out = []
    for line in (tmp / "bus.log").read_text(encoding="utf-8").splitlines():
        stamp, _, frame, direction = line.split()
        can_id, _, data = frame.partition("#")
        out.append((float(stamp.strip("()")), int(can_id, 16), bytes.fromhex(data), direction))
    return out


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.array_equal(a, b, equal_nan=True))


def test_the_dp200_commands_what_the_reference_commands(tmp_path: Path) -> None:
    """Same seed, same scenario: every trace (rod, forces, depths, statusword) is identical,
    sample for sample, through boot, a step, a sensor fault and a power cycle."""
    _, own = _run(tmp_path / "own", lambda: sowing_depth_fuzzy_pid(**PARAMS), {})
    ctl, theirs = _run(tmp_path / "dp200", lambda: sowing_depth_dp200(**PARAMS), DP200_RIG)
    assert np.ptp(own["rod_position_mm"]) > 5.0                     # the rod was driven
    assert np.nanmax(own["sensed_depth_mm"]) > 35.0                 # and followed the step
    assert isinstance(ctl, DbcDepthController) and ctl.config_error is None
    assert sorted(theirs) == sorted(own)
    for name in own:
        assert _same(theirs[name], own[name]), name


def test_the_drive_takes_the_dp200s_pdos(tmp_path: Path) -> None:
    """The drive accepts every configuration write (no SDO abort), then sends and takes only
    the DP-200's PDOs: its TPDO1 at 0x1A2 on every SYNC, its event-driven TPDO3 at 0x2A2 every
    100 ms, nothing at the EDS's default COB-IDs; the DP-200 commands it at 0x302."""
    scenario = dataclasses.replace(_scenario(), duration_s=1.0, events=())
    ctl, _ = _run(tmp_path, lambda: sowing_depth_dp200(**PARAMS), DP200_RIG, scenario)
    assert isinstance(ctl, DbcDepthController)
    assert len(ctl.configuration) == 30     # 6 invalidated, 3 PDOs mapped, heartbeat time
    frames = _bus(tmp_path)
    answers = [data[0] for _, can_id, data, _ in frames if can_id == 0x582]
    assert len(answers) == 30 + 1 and set(answers) == {0x60}      # config, then the mode
    drive = {can_id for _, can_id, _, way in frames if way == "T" and can_id < 0x800}
    assert {0x1A2, 0x2A2} <= drive and not drive & {0x182, 0x282, 0x382}
    syncs = sum(1 for _, can_id, _, _ in frames if can_id == 0x080)
    feedback = [t for t, can_id, _, _ in frames if can_id == 0x1A2]
    assert syncs - 2 <= len(feedback) <= syncs                     # on SYNC once started
    diagnosis = np.diff([t for t, can_id, _, _ in frames if can_id == 0x2A2])
    assert np.allclose(diagnosis, 0.1)
    commands = {can_id for _, can_id, _, way in frames if way == "R" and 0x180 < can_id < 0x580}
    assert commands == {0x18A, 0x302}                   # its status and the drive's RPDO1
    nmt = [data for _, can_id, data, _ in frames if can_id == 0x000]
    assert nmt == [bytes([0x01, 0x02])]                             # started once, configured


def test_a_refused_configuration_leaves_the_drive_stopped(tmp_path: Path) -> None:
    """The configuration can fail: a mapping of the statusword (read-only) into the drive's
    RPDO is refused with SDO abort 0x06040041; the DP-200 says which write, does not start
    the drive and reports Fault; the rod never moves."""
    bad = (PdoConfig("rpdo", 1, "DP_DriveCommand", ((0x60FF, 0, 32), (0x6041, 0, 16)), 1),
           *DP200_SIGNALS.drive_pdos[1:])
    signals = dataclasses.replace(DP200_SIGNALS, drive_pdos=bad)
    scenario = dataclasses.replace(_scenario(), duration_s=1.0, events=())
    ctl, traces = _run(tmp_path, lambda: DbcDepthController(DP200_DATABASE, signals, PARAMS),
                       DP200_RIG, scenario)
    assert isinstance(ctl, DbcDepthController)
    assert ctl.config_error is not None
    assert "0x1600:02" in ctl.config_error and "0x06040041" in ctl.config_error
    frames = _bus(tmp_path)
    db = cantools.database.load_file(str(DP200_DATABASE))
    status = [data for _, can_id, data, _ in frames if can_id == 0x18A]
    assert status and db.decode_message(0x18A, status[-1])["State"] == "Fault"
    assert not [f for f in frames if f[1] == 0x000]                  # no NMT start
    assert np.ptp(traces["rod_position_mm"]) == 0.0


def test_the_database_is_held_to_the_mapping(tmp_path: Path) -> None:
    """A database whose drive frame is not what the PDO mapping makes is refused by name."""
    text = DP200_DATABASE.read_text(encoding="utf-8").replace(
        " SG_ TargetVelocity : 0|32@1- (0.01,0)", " SG_ TargetVelocity : 16|32@1- (0.01,0)")
    text = text.replace(" SG_ Controlword : 32|16@1+", " SG_ Controlword : 0|16@1+")
    path = tmp_path / "swapped.dbc"
    path.write_text(text, encoding="utf-8")
    assert check_against_database(DP200_SIGNALS.drive_pdos,
                                  cantools.database.load_file(str(DP200_DATABASE)))
    with pytest.raises(ValueError, match="DP_DriveCommand"):
        DbcDepthController(path, DP200_SIGNALS, PARAMS)


def test_unknown_parameters_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="kp9"):
        dp200(kp9=1.0)


def test_a_wrong_status_map_is_seen_by_the_comparison(tmp_path: Path) -> None:
    """The comparison can fail where the check cannot see: a binding that sends the
    inclinometer's "ok" as the hub's OpenCircuit passes `hil profile check`, and the DP-200
    never regulates (it holds the roller), so the rod differs from the reference's."""
    wrong = _binding(tmp_path, 'TiltXState", multiplexer = "Channel", rows = [0], '
                               'values = { 0 = 1, 1 = 2,',
                     'TiltXState", multiplexer = "Channel", rows = [0], '
                     'values = { 0 = 2, 1 = 1,')
    assert _check(tmp_path, wrong).returncode == 0
    scenario = dataclasses.replace(_scenario(), duration_s=3.0, events=(
        Event(at_s=1.0, set={"target_depth_mm": 40.0}),))
    _, own = _run(tmp_path / "own", lambda: sowing_depth_fuzzy_pid(**PARAMS), {}, scenario)
    _, theirs = _run(tmp_path / "wrong", lambda: sowing_depth_dp200(**PARAMS),
                     {"wiring": {"binding_file": str(wrong)}}, scenario)
    assert np.ptp(own["rod_position_mm"]) > 5.0
    assert np.ptp(theirs["rod_position_mm"]) < 0.5


def _binding(tmp: Path, old: str, new: str) -> Path:
    """The DP-200's binding with ``old`` replaced (it must occur), beside a copy of its DBC."""
    text = BINDING.read_text(encoding="utf-8")
    assert old in text, old
    shutil.copyfile(DP200_DATABASE, tmp / DP200_DATABASE.name)
    path = tmp / "variant.binding.toml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def _check(tmp: Path, binding: Path) -> subprocess.CompletedProcess[str]:
    profile = tmp / PROFILE.name          # a profile is named as its file
    profile.write_text(PROFILE.read_text(encoding="utf-8").replace(
        'binding = "depthpro_dp200.binding.toml"', f'binding = "{binding.name}"'),
        encoding="utf-8")
    return subprocess.run([HIL, "profile", "check", str(profile)], capture_output=True,
                          text=True, cwd=REPO)


@pytest.mark.parametrize(("old", "new", "said"), [
    # a wrong scaling: the inclinometer read as mV where the database says V (x 1000)
    ('signal = "ArmTiltX", multiplexer', 'signal = "ArmTiltX", unit = "mV", multiplexer',
     "[quantities.inclinometer_x.unit] DP_SensorHub.ArmTiltX is in 'V' by the database; the "
     "binding says 'mV' (a factor of 0.001 on every value)"),
    # a missing signal: the depth sensor not bound at all
    ('inclinometer_x = { message = "DP_SensorHub", signal = "ArmTiltX", multiplexer = '
     '"Channel", rows = [0] }\n', "",
     "[quantities.inclinometer_x] the rig needs inclinometer_x"),
    # a missing signal: bound to a name the database does not have
    ('signal = "TargetDepth"', 'signal = "TargetDepthMm"',
     "DP_Setpoint has no signal 'TargetDepthMm'"),
])
def test_must_fail_bindings_are_refused_by_the_check(tmp_path: Path, old: str, new: str,
                                                     said: str) -> None:
    done = _check(tmp_path, _binding(tmp_path, old, new))
    assert done.returncode == 2, done.stdout + done.stderr
    assert said in done.stderr
    assert "Traceback" not in done.stderr


def test_the_profile_checks_clean() -> None:
    done = subprocess.run([HIL, "profile", "check", str(PROFILE)], capture_output=True,
                          text=True, cwd=REPO)
    assert done.returncode == 0, done.stderr
    assert not [line for line in (done.stdout + done.stderr).splitlines()
                if line.startswith("hil: error")], done.stderr


def test_the_generated_binding_is_what_bind_writes(tmp_path: Path) -> None:
    """The README's starting binding is the tool's unedited output."""
    database = tmp_path / DP200_DATABASE.name
    shutil.copyfile(DP200_DATABASE, database)
    out = tmp_path / "start.toml"
    subprocess.run([HIL, "profile", "bind", str(database), "--rig", "sowing_depth", "-o",
                    str(out)], check=True, capture_output=True)
    committed = EXAMPLE / "depthpro_dp200.generated.binding.toml"
    assert out.read_text(encoding="utf-8") == committed.read_text(encoding="utf-8")


def test_the_readme_quotes_the_check() -> None:
    """The README quotes what ``hil profile check`` says of the unedited binding, line for line
    (paths shortened to ``…``), so a change of the check or of ``hil profile bind`` shows."""
    readme = (EXAMPLE / "README.md").read_text(encoding="utf-8")
    quoted = readme.split("```text\n", 1)[1].split("```", 1)[0].splitlines()
    done = subprocess.run([HIL, "profile", "check",
                           str(EXAMPLE / "depthpro-dp200-first-try.toml")],
                          capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 2, done.stderr
    said = [re.sub(r"\S*depthpro[-_]dp200[.-]", "…", line)
            for line in (done.stdout + done.stderr).splitlines() if line.startswith("hil: ")]
    assert said == quoted


@pytest.mark.slow
def test_the_dp200_qualifies_with_the_reference_measurements(tmp_path: Path) -> None:
    """``hil qualify`` of both profiles, fast and robustness suites, lockstep on the inline
    bus, seed 0: every control measurement is the same number."""
    records = {name: qualified_measurements(HIL, profile, tmp_path / name, bus="inline",
                                            prefix="depth.", cwd=REPO)
               for name, profile in (("ref", REFERENCE), ("dp200", PROFILE))}
    assert len(records["ref"]) > 20
    assert records["dp200"] == records["ref"]
