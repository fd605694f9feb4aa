"""The longer kernel CAN checks inside the guest (``kernel_can`` and ``slow``): a short
qualification of the C firmware of each rig over ``socketcan:vcan0``, and a real-time run on
vcan with its timing health in the record."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.kernel.conftest import VCAN, hil, read_bus_log

pytestmark = [pytest.mark.kernel_can, pytest.mark.slow]

SUBSETS = {
    "fertilizer-piecewise-pid-firmware": "test_flow_step",
    "sowing-depth-fuzzy-pid-firmware": "test_depth_step",
}


@pytest.mark.parametrize("profile", sorted(SUBSETS))
def test_short_qualification_over_vcan(profile: str, tmp_path: Path) -> None:
    out = tmp_path / "q"
    done = hil("qualify", f"dut_profiles/{profile}.toml", "--bus", f"socketcan:{VCAN}",
               "--clock", "lockstep", "--suite", "fast", "-k", SUBSETS[profile],
               "--out", str(out), timeout=1500)
    record = json.loads((out / "record.json").read_text())
    assert done.returncode == 0, (record["verdict"], done.stderr[-2000:])
    assert record["verdict"] == "pass" and record["bus"] == f"socketcan:{VCAN}"
    passed = [t for t in record["tests"] if t["outcome"] == "passed"]
    assert passed and len(record["measurements"]) >= 3
    for run in record["runs"]:
        assert run["error"] in (None, ""), run
        assert read_bus_log(out / run["dir"] / "bus.log"), run


def test_real_time_run_on_vcan_records_its_timing_health(tmp_path: Path) -> None:
    out = tmp_path / "rt"
    done = hil("run", "--dut", "dut_profiles/fertilizer-piecewise-pid-firmware.toml",
               "--scenario", "bench-step-23", "--bus", f"socketcan:{VCAN}",
               "--clock", "realtime", "--out", str(out), timeout=300)
    assert done.returncode in (0, 1), done.stderr[-2000:]
    record = json.loads((out / "record.json").read_text())
    timing = record["timing"]
    assert timing["mode"] == "realtime"
    for key in ("lateness_p50_s", "lateness_p99_s", "lateness_max_s", "misses", "stalls"):
        assert isinstance(timing[key], int | float), (key, timing)
    assert isinstance(timing["valid"], bool) and isinstance(timing["invalid_reasons"], list)
    print(f"\nreal time on vcan (guest): p99 lateness {timing['lateness_p99_s'] * 1e6:.0f} us, "
          f"max {timing['lateness_max_s'] * 1e3:.2f} ms, misses {timing['misses']}, "
          f"valid {timing['valid']} {timing['invalid_reasons']}")
    # the firmware answered over the kernel's bus in real time: heartbeats and commands
    frames = read_bus_log(out / "bus.log")
    ids = {m.arbitration_id for m in frames}
    assert {0x220, 0x710} <= ids, sorted(hex(i) for i in ids)
    assert record["dut"]["exit_code"] == 0, record["dut"]
