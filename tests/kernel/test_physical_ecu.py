"""A DUT the rig does not start: a physical ECU, played by a separate process.

The reference daemon, started by the test (not by the rig) in real time, is the ECU; the rig
qualifies it with ``hil qualify`` of a ``kind = "physical"`` profile: on the software bus
served by ``hil bus serve`` (socketcand) on the host, and on kernel vcan inside the user-mode
Linux guest. Scenarios that power-cycle the DUT are skipped with that reason, the rest judge
it; no heartbeat is a setup error (exit 2), after the endpoints the ECU needs were printed and
written to the run directory.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil.dut.profile import load_profile
from tests.kernel.conftest import VCAN, bus_server, ecu_player, hil, physical_profile, read_bus_log

FAST_SUBSET = {
    "fertilizer": ("fertilizer-piecewise-pid-daemon", "test_flow_step and 23 or test_dut_restart"),
    "sowing_depth": ("sowing-depth-fuzzy-pid-daemon",
                     "test_depth_step or fault-dut-restart"),
}


def _error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("hil: error")]


@pytest.mark.parametrize("rig", ["fertilizer", "sowing_depth"])
def test_no_heartbeat_is_a_setup_error_after_the_endpoints_are_out(rig: str,
                                                                   tmp_path: Path) -> None:
    profile = physical_profile(rig, tmp_path, ready_timeout_s=1.0)
    scenario = "bench-step-23" if rig == "fertilizer" else "depth-step"
    with bus_server() as spec:
        done = hil("run", "--dut", str(profile), "--scenario", scenario, "--clock", "realtime",
                   "--bus", spec, "--out", str(tmp_path / "run"), timeout=120)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    errors = _error_lines(done.stderr)
    assert len(errors) == 1, done.stderr
    heartbeat = "0x710" if rig == "fertilizer" else "0x701"
    assert f"no heartbeat {heartbeat}" in errors[0] and spec in errors[0]
    # it names the endpoints file where it is once the command has ended (the run's files
    # are staged while it runs, then moved into --out), never the staging directory
    assert f"endpoints: {tmp_path / 'run' / 'ecu-endpoints.json'}" in errors[0], errors[0]
    # the endpoints came first, on stderr and in the run directory
    lines = done.stderr.splitlines()
    join = next(i for i, line in enumerate(lines) if f"join bus {spec}" in line)
    assert join < lines.index(errors[0])
    found = json.loads((tmp_path / "run" / "ecu-endpoints.json").read_text())
    assert found["bus"] == spec and found["heartbeat_id"] == heartbeat
    assert found["bitrate_bps"] == 250_000
    if rig == "sowing_depth":
        assert found["gnss_port"].startswith("/dev/pts/"), found
        assert f"GNSS receiver (NMEA 0183): {found['gnss_port']}" in done.stderr
    else:
        assert found["gnss_port"] is None and "GNSS" not in done.stderr


def test_qualify_without_the_ecu_is_a_setup_error_not_a_fail(tmp_path: Path) -> None:
    profile = physical_profile("fertilizer", tmp_path, ready_timeout_s=1.0)
    with bus_server() as spec:
        done = hil("qualify", str(profile), "--clock", "realtime", "--bus", spec,
                   "-k", "test_flow_step and 23", "--out", str(tmp_path / "q"), timeout=300)
    assert done.returncode == 2, done.stdout[-3000:] + done.stderr
    record = json.loads((tmp_path / "q" / "record.json").read_text())
    assert record["verdict"] == "error"
    assert "no heartbeat 0x710" in record["error"]


def qualify_physical(rig: str, bus: str, tmp_path: Path, *,
                     invalid_bench_ok: bool = False) -> dict:
    """Qualify the physical profile of ``rig`` on ``bus`` (the fast subset and the restart
    scenario) with the reference daemon playing the ECU on the same bus.

    The setup is checked whatever the bench timing: the ECU was found by its heartbeat on that
    bus, every run wrote its endpoints and carried the ECU's frames, the restart scenario was
    skipped for the stated reason. The verdict is checked only on a valid bench; an invalid one
    (the machine's load, or an emulated kernel's real time) skips the test unless
    ``invalid_bench_ok``.
    """
    daemon, keyword = FAST_SUBSET[rig]
    out = tmp_path / "q"
    with ecu_player(daemon, bus) as ecu:
        done = hil("qualify", str(physical_profile(rig, tmp_path)), "--clock", "realtime",
                   "--bus", bus, "--suite", "fast,robustness", "-k", keyword,
                   "--out", str(out), timeout=900)
        assert ecu.poll() is None, "the ECU process died during the qualification"
    record = json.loads((out / "record.json").read_text())
    assert record["verdict"] != "error", (record.get("error"), done.stderr[-2000:])
    assert record["dut"]["kind"] == "physical"
    tests = {t["nodeid"]: t for t in record["tests"]}
    restart = [t for n, t in tests.items() if "restart" in n]
    assert restart and all(t["outcome"] == "skipped" for t in restart), restart
    assert all("cannot power-cycle a physical ECU" in t["message"] for t in restart)
    profile = load_profile(physical_profile(rig, tmp_path))
    assert record["runs"]
    for run in record["runs"]:
        assert run["error"] in (None, ""), run
        endpoints = json.loads((out / run["dir"] / "ecu-endpoints.json").read_text())
        assert endpoints["bus"] == bus
        ids = {m.arbitration_id for m in read_bus_log(out / run["dir"] / "bus.log")}
        assert profile.wiring.heartbeat_id in ids and set(profile.wiring.command_ids) & ids
    timing = record.get("timing") or {}
    if record["verdict"] == "invalid-bench":
        reasons = timing.get("invalid_reasons")
        if invalid_bench_ok:
            print(f"\ninvalid bench (real time under emulation): {reasons}")
            return record
        pytest.skip(f"the rig's real-time timing was out of bounds ({reasons}): says nothing "
                    "about the DUT")
    assert done.returncode in (0, 1), done.stdout[-3000:] + done.stderr
    assert record["verdict"] in ("pass", "fail")
    judged = [t for n, t in tests.items() if "restart" not in n]
    assert judged and all(t["outcome"] in ("passed", "failed") for t in judged), judged
    measured = [m for m in record["measurements"] if m["value"] == m["value"]]  # not NaN
    assert measured, record["measurements"]
    return record


@pytest.mark.slow   # the default run makes this qualification as docs/guide/physical-ecu.md's
#                   example (tests/test_docs_examples.py, the same command over hil bus serve,
#                   exit 0 or an invalid bench): 26 s of the 6-minute budget, not twice
def test_qualify_a_physical_fertilizer_ecu_over_hil_bus_serve(tmp_path: Path) -> None:
    with bus_server() as spec:
        record = qualify_physical("fertilizer", spec, tmp_path)
    # the reference controller, played as an outside ECU, behaves on the bus; its control
    # measurements are judged (qualify_physical checks they have values). Their verdict is
    # not asserted: in real time each run draws its own sensor noise and flute phase, and the
    # reference does not yet pass on every sample (issue 16: the 23 g/s overshoot)
    bad_bus = [m for m in record["measurements"]
               if m["name"].startswith("bus.") and m["outcome"] in ("fail", "error")]
    assert not bad_bus, bad_bus


@pytest.mark.slow
def test_qualify_a_physical_depth_ecu_over_hil_bus_serve(tmp_path: Path) -> None:
    with bus_server() as spec:
        qualify_physical("sowing_depth", spec, tmp_path)


@pytest.mark.kernel_can
@pytest.mark.slow
@pytest.mark.parametrize("rig", ["fertilizer", "sowing_depth"])
def test_qualify_a_physical_ecu_on_vcan(rig: str, tmp_path: Path) -> None:
    # real time inside the emulated kernel is rarely a valid bench (one emulated CPU on a shared
    # host): the ECU's setup over vcan is checked either way, the verdict when the bench is valid
    qualify_physical(rig, f"socketcan:{VCAN}", tmp_path, invalid_bench_ok=True)
