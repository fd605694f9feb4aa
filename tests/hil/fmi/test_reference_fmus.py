"""The reference controllers as FMUs, built from their C cores by their profiles' [build].

The bus-level FMU of the fertilizer firmware (firmware/fmu/fertilizer_lsbus) on the inline bus
gives the same bus log, byte for byte, as the firmware program over the software bus: the
same frames at the same times, through a set-point step, a field run with speeds and a
power cycle.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.rig.runner import RunOptions, run_scenario
from plant_emulators.fertilizer.rig import FertilizerRig

ROOT = Path(__file__).resolve().parents[3]
FIRMWARE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-firmware.toml"
LSBUS = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-fmu-lsbus.toml"


def bus_log(tmp: Path, profile_path: Path, bus: str, scenario: str, duration_s: float) -> bytes:
    profile = load_profile(profile_path)
    dut, _ = make_dut(profile, bus=bus, clock="lockstep", log_dir=tmp)
    sc = dataclasses.replace(FertilizerRig.load_scenario(scenario), duration_s=duration_s)
    result = run_scenario(FertilizerRig, sc, dut,
                          RunOptions(out_dir=tmp, bus=bus, clock="lockstep",
                                     **profile_run_options(profile)))
    assert result.record.get("error") in (None, ""), result.record.get("error")
    return (tmp / "bus.log").read_bytes()


@pytest.mark.parametrize("scenario, duration_s", [
    ("bench-step-23", 10.0),
    ("field-stop-go", 15.0),
    ("fault-dut-restart", 16.0),
])
def test_the_lsbus_fmu_gives_the_firmware_bus_log_byte_for_byte(
        tmp_path: Path, scenario: str, duration_s: float) -> None:
    fmu = bus_log(tmp_path / "fmu", LSBUS, "inline", scenario, duration_s)
    firmware = bus_log(tmp_path / "fw", FIRMWARE, "softbus", scenario, duration_s)
    assert fmu.count(b"\n") > 100 * duration_s * 0.9 / 10   # the run wrote its frames
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
