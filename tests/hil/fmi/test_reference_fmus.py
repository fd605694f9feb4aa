"""The reference controllers as FMUs, built from their C cores by their profiles' [build].

The bus-level FMUs of the fertilizer and depth firmware (firmware/fmu/*_lsbus) and the
signal-level fertilizer FMU (firmware/fmu/fertilizer_signal) on the inline bus give the same
bus log, byte for byte, as the firmware programs over the software bus: the same frames at the
same times, through set-point steps, a field run with speeds, a stale sensor and a power
cycle.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.rig.base import Rig
from hil.rig.runner import RunOptions, run_scenario
from plant_emulators.fertilizer.rig import FertilizerRig
from plant_emulators.sowing_depth.rig import SowingDepthRig

ROOT = Path(__file__).resolve().parents[3]
FIRMWARE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-firmware.toml"
LSBUS = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-fmu-lsbus.toml"
SIGNAL = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-fmu-signal.toml"
DEPTH_FIRMWARE = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-firmware.toml"
DEPTH_LSBUS = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-fmu-lsbus.toml"


def bus_log(tmp: Path, profile_path: Path, bus: str, scenario: str, duration_s: float, *,
            rig: type[Rig] = FertilizerRig) -> bytes:
    profile = load_profile(profile_path)
    dut, _ = make_dut(profile, bus=bus, clock="lockstep", log_dir=tmp)
    sc = dataclasses.replace(rig.load_scenario(scenario), duration_s=duration_s)
    result = run_scenario(rig, sc, dut,
                          RunOptions(out_dir=tmp, bus=bus, clock="lockstep",
                                     **profile_run_options(profile)))
    assert result.record.get("error") in (None, ""), result.record.get("error")
    return (tmp / "bus.log").read_bytes()


SLOW = pytest.mark.slow


@pytest.mark.parametrize("fmu_profile, scenario, duration_s", [
    (LSBUS, "bench-step-23", 10.0),
    pytest.param(SIGNAL, "bench-step-23", 10.0, marks=SLOW),
    pytest.param(LSBUS, "fault-dut-restart", 16.0, marks=SLOW),
    (SIGNAL, "bench-lot-calibrated", 8.0),
    pytest.param(SIGNAL, "fault-dut-restart", 16.0, marks=SLOW),
    pytest.param(LSBUS, "field-stop-go", 45.0, marks=SLOW),
    pytest.param(SIGNAL, "field-stop-go", 45.0, marks=SLOW),
    pytest.param(LSBUS, "fault-sensor-stale", 14.0, marks=SLOW),
    pytest.param(SIGNAL, "fault-sensor-stale", 14.0, marks=SLOW),
], ids=lambda v: v.stem.rsplit("-", 1)[-1] if isinstance(v, Path) else str(v))
def test_the_fmus_give_the_firmware_bus_log_byte_for_byte(
        tmp_path: Path, fmu_profile: Path, scenario: str, duration_s: float) -> None:
    fmu = bus_log(tmp_path / "fmu", fmu_profile, "inline", scenario, duration_s)
    firmware = bus_log(tmp_path / "fw", FIRMWARE, "softbus", scenario, duration_s)
    assert fmu.count(b"\n") > 100 * duration_s * 0.9 / 10   # the run wrote its frames
    assert fmu == firmware


@pytest.mark.parametrize("scenario, duration_s", [
    ("depth-step", 4.0),
    pytest.param("depth-step", 60.0, marks=SLOW),
    pytest.param("fault-dut-restart", 30.0, marks=SLOW),
])
def test_the_depth_lsbus_fmu_gives_the_firmware_bus_log_byte_for_byte(
        tmp_path: Path, scenario: str, duration_s: float) -> None:
    """The depth controller: a CANopen master that configures the drive by SDO at boot and
    reads the GNSS receiver's serial port (the rig's AGRIHIL_GNSS_PORT, a string parameter)."""
    fmu = bus_log(tmp_path / "fmu", DEPTH_LSBUS, "inline", scenario, duration_s,
                  rig=SowingDepthRig)
    firmware = bus_log(tmp_path / "fw", DEPTH_FIRMWARE, "softbus", scenario, duration_s,
                       rig=SowingDepthRig)
    assert fmu.count(b"\n") > 500 * duration_s
    assert fmu == firmware


def test_a_different_controller_gives_a_different_bus_log(tmp_path: Path) -> None:
    """The comparison can fail: the FMU with another meter map commands other millivolts."""
    text = LSBUS.read_text(encoding="utf-8").replace("ff_coeff = 4.390", "ff_coeff = 4.0")
    other = tmp_path / LSBUS.name
    other.write_text(text.replace('"plant_emulators/', f'"{ROOT}/plant_emulators/'),
                     encoding="utf-8")
    fmu = bus_log(tmp_path / "fmu", other, "inline", "bench-step-23", 6.0)
    firmware = bus_log(tmp_path / "fw", FIRMWARE, "softbus", "bench-step-23", 6.0)
    assert fmu != firmware


@pytest.mark.slow
def test_both_fmus_qualify_with_the_firmware_measurements(tmp_path: Path) -> None:
    """``hil qualify`` (fast and robustness suites, seed 0): every control measurement of the
    LS-BUS FMU and of the signal-level FMU (inline) equals the firmware's (software bus)."""
    import shutil

    from tests.helpers.same_measurements import qualified_measurements

    hil = shutil.which("hil") or "hil"
    firmware = qualified_measurements(hil, FIRMWARE, tmp_path / "fw", bus="softbus",
                                      prefix="flow.", cwd=ROOT)
    assert len(firmware) >= 30
    for profile in (LSBUS, SIGNAL):
        got = qualified_measurements(hil, profile, tmp_path / profile.stem, bus="inline",
                                     prefix="flow.", cwd=ROOT)
        assert got == firmware, profile.name


@pytest.mark.slow
def test_a_bad_fmu_fails_qualification(tmp_path: Path) -> None:
    """The same FMU running the open-loop law (no flow feedback) fails the step suite."""
    import subprocess
    import sys

    text = LSBUS.read_text(encoding="utf-8").replace('mode = "physical"', 'mode = "open-loop"')
    text = text.replace("ff_coeff = 4.390", "")
    bad = tmp_path / LSBUS.name
    bad.write_text(text.replace('"plant_emulators/', f'"{ROOT}/plant_emulators/'),
                   encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "hil", "qualify", str(bad), "--bus", "inline",
                           "--suite", "fast", "-k", "step", "--out", str(tmp_path / "q"),
                           "--quiet"], cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]
