"""The sowing-depth reference controller as an FMU qualifies as its firmware does.

The depth firmware as an LS-BUS FMU (firmware/fmu/depth_lsbus, built by its profile's
[build]) on the inline bus gives every control measurement (``depth.*``) of the fast and
robustness suites the firmware's over the software bus (slow: two ``hil qualify`` runs), and
the same FMU running a defective law fails qualification. The default run keeps a fast check
that the law's gains reach the FMU and change what it commands (without it, the must-fail could
pass for the wrong reason). Its bus logs are compared byte for byte in test_reference_fmus.py.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest

from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.rig.runner import RunOptions, run_scenario
from plant_emulators.sowing_depth.rig import SowingDepthRig
from tests.helpers.same_measurements import qualified_measurements

ROOT = Path(__file__).resolve().parents[3]
HIL = str(Path(sys.executable).with_name("hil"))
FIRMWARE = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-firmware.toml"
LSBUS = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-fmu-lsbus.toml"
#: the defective law: the high-gain must-fail's proportional preset (Kp0 = 30 mm/s per mm, ten
#: times the contract's; dut_profiles/must_fail/sowing-depth-high-gain-daemon.toml): it
#: limit-cycles against the roller's transport delay, overshoots every step and never settles
HIGH_GAIN = ("kp0 = 3.0", "kp0 = 30.0")


def defective(tmp_path: Path) -> Path:
    """The LS-BUS FMU's profile with the high-gain law (its paths made absolute)."""
    text = LSBUS.read_text(encoding="utf-8")
    assert HIGH_GAIN[0] in text
    text = text.replace(*HIGH_GAIN).replace('name = "sowing-depth-fuzzy-pid-fmu-lsbus"',
                                            'name = "sowing-depth-high-gain-fmu-lsbus"')
    path = tmp_path / "sowing-depth-high-gain-fmu-lsbus.toml"
    path.write_text(text.replace('"plant_emulators/', f'"{ROOT}/plant_emulators/'),
                    encoding="utf-8")
    return path


def drive_commands(tmp: Path, profile_path: Path, seconds: float) -> list[bytes]:
    """The payloads of the FMU's RPDO2 (controlword, target velocity) on the inline bus."""
    profile = load_profile(profile_path)
    dut, _ = make_dut(profile, bus="inline", clock="lockstep", log_dir=tmp)
    sc = dataclasses.replace(SowingDepthRig.load_scenario("depth-step"), duration_s=seconds)
    result = run_scenario(SowingDepthRig, sc, dut,
                          RunOptions(out_dir=tmp, bus="inline", clock="lockstep",
                                     **profile_run_options(profile)))
    assert result.record.get("error") in (None, ""), result.record.get("error")
    out = []
    for line in (tmp / "bus.log").read_text().splitlines():
        can_id, _, data = line.split()[2].partition("#")
        if can_id == "302":
            out.append(bytes.fromhex(data))
    return out


def test_the_law_s_gains_reach_the_depth_fmu(tmp_path: Path) -> None:
    """Kp0 = 30 commands other rod velocities than the contract's Kp0 = 3 from the same
    plant, once the drive is enabled; the controlwords (the CiA 402 enable sequence) agree."""
    good = drive_commands(tmp_path / "good", LSBUS, 1.0)
    bad = drive_commands(tmp_path / "bad", defective(tmp_path), 1.0)
    assert len(good) == len(bad) == 101              # one RPDO2 per SYNC, 0 to 1 s
    assert [c[:2] for c in good] == [c[:2] for c in bad]
    moving = [i for i, c in enumerate(good) if c[2:] != bytes(4)]
    assert moving, "the contract's law never commanded a velocity in 1 s"
    assert any(good[i] != bad[i] for i in moving)


@pytest.mark.slow
def test_the_depth_lsbus_fmu_qualifies_with_the_firmware_measurements(tmp_path: Path) -> None:
    """``hil qualify`` (fast and robustness suites, seed 0): every control measurement of the
    LS-BUS FMU (inline) is the firmware's (software bus), to the last digit."""
    firmware = qualified_measurements(HIL, FIRMWARE, tmp_path / "fw", bus="softbus",
                                      prefix="depth.", cwd=ROOT)
    assert len(firmware) > 20
    assert ("depth.fault.speed_loss.rod_travel", "{}") in firmware
    fmu = qualified_measurements(HIL, LSBUS, tmp_path / "fmu", bus="inline", prefix="depth.",
                                 cwd=ROOT)
    assert fmu == firmware


@pytest.mark.slow
def test_the_depth_fmu_with_a_defective_law_fails_qualification(tmp_path: Path) -> None:
    """The same FMU with the high-gain law fails the step suite (exit 1) on the measurements
    that judge it: the overshoot and the response time of the set-point steps."""
    out = tmp_path / "q"
    done = subprocess.run([HIL, "qualify", str(defective(tmp_path)), "--bus", "inline",
                           "--suite", "fast", "-k", "step", "--out", str(out), "--quiet"],
                          cwd=ROOT, capture_output=True, text=True, timeout=1800)
    assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]
    record = json.loads((out / "record.json").read_text(encoding="utf-8"))
    failed = {m["name"] for m in record["measurements"] if m["outcome"] == "fail"}
    assert {"depth.step.overshoot", "depth.step.response_time"} <= failed, failed
