"""``hil run`` in lockstep over kernel CAN (``socketcan:vcan0``), both rigs, daemon and C firmware.

The C firmware talks to vcan0 through its SocketCAN HAL (``firmware/hal/can_socketcan.c``).
Each run's bus log is checked frame by frame (SYNC every control period, the DUT's command
frames answering each one, its heartbeat at its period, time never going back), and its traces
must equal those of the same run over the software bus: the kernel's bus carries exactly what
the software bus does.
"""

from __future__ import annotations

import collections
import json
from pathlib import Path

import numpy as np
import pytest

from hil.dut.profile import load_profile
from hil.record.traces import load_traces
from tests.kernel.conftest import ROOT, VCAN, hil, read_bus_log

pytestmark = pytest.mark.kernel_can

SYNC = 0x080
#: short versions of the rigs' step scenarios (the packaged ones last 23 s and 60 s): what is
#: checked here is the transport, frame by frame, not the controller's settling
SHORT = {
    "fertilizer": """
name = "bench-step-short"
description = "bench step 0 -> 23 g/s per row at 3 s, 7 s after it"
rig = "fertilizer"
duration_s = 10.0
seed = 23
[initial]
terminal_mode = 1.0
enable = 0.0
target_flow_gps = 23.0
[[events]]
at_s = 3.0
set = { enable = 1.0 }
""",
    "sowing_depth": """
name = "depth-step-short"
description = "depth setpoint 30 -> 40 mm at 3 s, at 4 km/h"
rig = "sowing_depth"
duration_s = 8.0
seed = 1
[initial]
target_depth_mm = 30.0
ground_speed_mps = 1.1111
[[events]]
at_s = 3.0
set = { target_depth_mm = 40.0 }
""",
}
#: the default run covers each rig once and each transport once (python-can's SocketCAN bus in
#: the fertilizer daemon, the firmware's C HAL in the depth build); the other two are ``slow``
#: (together ~50 s inside the guest)
CASES = [
    ("fertilizer-piecewise-pid-daemon", "fertilizer"),
    pytest.param("fertilizer-piecewise-pid-firmware", "fertilizer", marks=pytest.mark.slow),
    pytest.param("sowing-depth-fuzzy-pid-daemon", "sowing_depth", marks=pytest.mark.slow),
    ("sowing-depth-fuzzy-pid-firmware", "sowing_depth"),
]


def _run(profile: str, scenario: str, bus: str, out: Path) -> dict:
    done = hil("run", "--dut", f"dut_profiles/{profile}.toml", "--scenario", scenario,
               "--bus", bus, "--clock", "lockstep", "--seed", "7", "--out", str(out))
    assert done.returncode == 0, done.stderr
    record = json.loads((out / "record.json").read_text())
    assert record.get("error") in (None, ""), record.get("error")
    return record


def _check_bus_log(path: Path, profile_name: str, duration_s: float) -> None:
    profile = load_profile(ROOT / "dut_profiles" / f"{profile_name}.toml")
    frames = read_bus_log(path)
    times = np.array([m.timestamp for m in frames])
    assert np.all(np.diff(times) >= 0), "bus log time goes back"
    counts = collections.Counter(m.arbitration_id for m in frames)
    rig_period_s = np.median(np.diff([m.timestamp for m in frames
                                      if m.arbitration_id == SYNC]))
    syncs = counts[SYNC]
    assert syncs == pytest.approx(duration_s / rig_period_s, abs=2), counts
    # the DUT answers every SYNC with its command frame(s)
    answered = max(counts[i] for i in profile.wiring.command_ids)
    assert answered >= syncs - 2, (answered, syncs)
    # and sends its heartbeat at its period
    beats = counts[profile.wiring.heartbeat_id]
    expected = duration_s * 1000.0 / profile.timing.heartbeat_period_ms
    assert beats == pytest.approx(expected, rel=0.05, abs=2), (beats, expected)


@pytest.mark.parametrize(("profile", "rig"), CASES)
def test_lockstep_run_over_vcan_matches_the_software_bus(profile: str, rig: str,
                                                         tmp_path: Path) -> None:
    path = tmp_path / "short.toml"
    path.write_text(SHORT[rig])
    scenario = str(path)
    record = _run(profile, scenario, f"socketcan:{VCAN}", tmp_path / "vcan")
    assert record["bus"] == f"socketcan:{VCAN}"
    assert record["dut"]["exit_code"] == 0, record["dut"]
    assert f"socketcan:{VCAN}" in record["dut"]["argv"], record["dut"]["argv"]
    _check_bus_log(tmp_path / "vcan" / "bus.log", profile, float(record["duration_s"]))
    traces, _ = load_traces(tmp_path / "vcan" / "traces.npz")
    _run(profile, scenario, "softbus", tmp_path / "softbus")
    reference, _ = load_traces(tmp_path / "softbus" / "traces.npz")
    assert traces.keys() == reference.keys()
    for name in traces:
        np.testing.assert_array_equal(traces[name], reference[name], err_msg=name)
