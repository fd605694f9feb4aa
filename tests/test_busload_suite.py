"""The bus-load suite (``--suite busload``): real time on a software bus paced at 250 kbit/s
and loaded to ~80 %. The reference passes, a controller that ignores its setpoint fails on
``flow.busload.accuracy``, and a bus without a bit rate skips the suite with its reason.

The two real-time qualifications take ~1 minute each: they are in the slow set."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
IGNORES_SETPOINT = ROOT / "dut_profiles" / "must_fail" / "fertilizer-ignores-setpoint-daemon.toml"


def _qualify(profile: Path, out: Path, bus: str = "softbus") -> tuple[int, dict[str, Any]]:
    proc = subprocess.run([sys.executable, "-m", "hil", "qualify", str(profile), "--bus", bus,
                           "--suite", "busload", "--out", str(out), "--quiet"],
                          capture_output=True, text=True, cwd=ROOT, timeout=600, check=False)
    return proc.returncode, json.loads((out / "record.json").read_text())


def _judged_flow_busload(profile: Path, out: Path) -> tuple[int, dict[str, Any]]:
    """Exit status and the flow.busload.accuracy measurement of a judged run (skips the test
    when the machine could not hold real time: no verdict on the DUT then)."""
    rc, record = _qualify(profile, out)
    if record["verdict"] == "invalid-bench":
        pytest.skip("the machine could not hold real time: no verdict on the DUT")
    [m] = [m for m in record["measurements"] if m["name"] == "flow.busload.accuracy"]
    return rc, m


@pytest.mark.slow
def test_reference_passes_on_a_loaded_bus(tmp_path: Path) -> None:
    rc, m = _judged_flow_busload(REFERENCE, tmp_path / "q")
    assert rc == 0 and m["outcome"] in ("pass", "marginal"), m
    wire = float(re.search(r"([0-9.]+) % of the bit rate", m["note"]).group(1))
    assert 70.0 < wire < 90.0, m["note"]      # the rig's ~5 % plus the 75 % offered


@pytest.mark.slow
def test_setpoint_ignoring_controller_fails_on_a_loaded_bus(tmp_path: Path) -> None:
    rc, m = _judged_flow_busload(IGNORES_SETPOINT, tmp_path / "q")
    assert rc == 1 and m["outcome"] == "fail", m


def test_bus_without_a_bit_rate_skips_the_suite(tmp_path: Path) -> None:
    rc, record = _qualify(REFERENCE, tmp_path / "q", bus="inline")
    # nothing measured: a setup error (exit 2), never a verdict on the DUT
    assert rc == 2 and record["verdict"] == "error" and record["measurements"] == []
    [test] = [t for t in record["tests"] if "test_flow_busload" in t["nodeid"]]
    assert test["outcome"] == "skipped" and "bit rate" in test.get("message", ""), test


DEPTH_REFERENCE = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-daemon.toml"


@pytest.mark.slow
def test_depth_reference_on_a_loaded_bus(tmp_path: Path) -> None:
    """The depth field run (111 s real time) under load. On the 2-vCPU development VM the
    depth rig's real-time loop stalls up to ~40 ms unloaded and ~60 ms loaded (limit 50 ms),
    so the run may end ``invalid-bench``: the measurement is still recorded, never judged."""
    rc, record = _qualify(DEPTH_REFERENCE, tmp_path / "q")
    [m] = [m for m in record["measurements"] if m["name"] == "depth.busload.pass_rate"]
    wire = float(re.search(r"([0-9.]+) % of the bit rate", m["note"]).group(1))
    assert 75.0 < wire < 95.0, m["note"]      # the rig's ~30 % plus the 55 % offered
    if record["verdict"] == "invalid-bench":
        assert rc == 2
        pytest.skip(f"the machine could not hold real time ({m['value']:.1f} % pass rate "
                    f"recorded, not judged)")
    assert rc == 0 and m["outcome"] in ("pass", "marginal"), m
