"""The reference flow profiles' calibrated map comes from the documented rotation test."""

from __future__ import annotations

import math
import re
import statistics
import subprocess
import sys
import tomllib

from hil.dut.build import PROJECT_ROOT

SCRIPT = PROJECT_ROOT / "scripts" / "calibrate_meter.py"
CALIBRATED = ("fertilizer-piecewise-pid-daemon.toml", "fertilizer-piecewise-pid-firmware.toml")


def test_profiles_carry_the_rotation_tests_ff_coeff() -> None:
    proc = subprocess.run([sys.executable, str(SCRIPT)], capture_output=True, text=True,
                          cwd=PROJECT_ROOT, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    ratios = [float(x) for x in re.findall(r"weighed / expected = ([0-9.]+)", proc.stdout)]
    assert len(ratios) == 9                       # 3 rates x 3 repeats
    # the emulated fertilizer delivers ~3.5 % less than the meter's nominal map (rig.toml)
    assert all(0.93 < r < 0.99 for r in ratios), proc.stdout
    coeff = float(re.search(r"ff_coeff = ([0-9.]+)", proc.stdout).group(1))
    # an operator's rotation test is itself a measurement: the profiles carry its coefficient
    # within the standard error of its mean over the 9 weighings (~0.3 %), not to the last
    # digit, so a rig change that moves the noise of the day (issue #16's centred roller
    # spread: 4.390 -> 4.387) does not force a controller change; a real recalibration does
    sem = statistics.stdev(ratios) / math.sqrt(len(ratios)) / statistics.fmean(ratios)
    for name in CALIBRATED:
        with open(PROJECT_ROOT / "dut_profiles" / name, "rb") as f:
            carried = tomllib.load(f)["parameters"]["ff_coeff"]
        assert abs(carried / coeff - 1.0) <= sem, (name, carried, coeff, sem)


def test_calibration_reports_a_failed_run(tmp_path) -> None:
    broken = tmp_path / "broken.toml"
    broken.write_text("[dut]\nname = 'x'\n")
    proc = subprocess.run([sys.executable, str(SCRIPT), "--repeats", "1", "--profile",
                           str(broken)], capture_output=True, text=True, cwd=PROJECT_ROOT,
                          timeout=120, check=False)
    assert proc.returncode != 0
    assert "broken.toml" in proc.stderr + proc.stdout
