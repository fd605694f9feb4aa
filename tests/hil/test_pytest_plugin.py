"""The pytest plugin, tested the way users meet it: pytest in a subprocess."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

PROFILE = '''
[dut]
name = "toy-pi-inprocess"
version = "0.0.1"
kind = "inprocess"
rig = "fertilizer"
controller = "builtin-pi"

[launch]
inprocess = "plant_emulators.fertilizer.controllers:PiFlowController"

[wiring]
node_id = 0x10

[timing]
control_period_ms = 100

[limits]
"flow.step.overshoot" = { high = 5.0 }
"flow.step.steady_state_error" = { high = 1.0 }
'''

SUITE = '''
import numpy as np
import pytest

from hil.record import load_traces

pytestmark = [pytest.mark.hil_rig("fertilizer")]


@pytest.mark.hil_suite("fast")
def test_within_limits(hil_run, hil_measure):
    result = hil_run("bench-step-23")
    arrays, _ = load_traces(result.out_dir / "traces.npz")
    flow = arrays["flow_at_meter_1_gps"]
    assert flow.size > 1000
    hil_measure("flow.step.overshoot", 1.0, conditions={"target_gps": 23}, run=result)


@pytest.mark.hil_suite("fast")
def test_out_of_limits(hil_run, hil_measure):
    result = hil_run("bench-step-23")            # cached: the same run as above
    hil_measure("flow.step.steady_state_error", 7.5, conditions={"target_gps": 23},
                run=result)


@pytest.mark.hil_suite("robustness")
def test_robust(hil_measure):
    hil_measure("flow.step.overshoot", 2.0)


@pytest.mark.hil_rig("sowing_depth")
@pytest.mark.hil_suite("fast")
def test_other_rig(hil_measure):
    raise AssertionError("must be skipped for a fertilizer DUT")
'''


def _pytest(tmp_path: Path, *args: str, suite: str = SUITE) -> subprocess.CompletedProcess[str]:
    (tmp_path / "toy-pi-inprocess.toml").write_text(PROFILE)
    (tmp_path / "test_toy_suite.py").write_text(suite)
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-rs", "-c", "/dev/null",
         "--rootdir", str(tmp_path), "--import-mode=importlib", str(tmp_path / "test_toy_suite.py"),
         *args], capture_output=True, text=True, cwd=tmp_path, timeout=300)


def test_plugin_runs_measures_and_judges(tmp_path: Path) -> None:
    report = tmp_path / "qual"
    proc = _pytest(tmp_path, "--hil-dut", "toy-pi-inprocess.toml", "--hil-bus", "inline",
                   "--hil-report", str(report), "--hil-suite", "fast",
                   "--junitxml", str(tmp_path / "junit.xml"))
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1, out
    assert "1 failed, 1 passed, 1 skipped, 1 deselected" in out
    assert "flow.step.steady_state_error[target_gps=23] = 7.5 %: fail (limits None .. 1.0)" in out
    assert "a sowing_depth suite; the DUT toy-pi-inprocess drives the fertilizer rig" in out
    assert "agrihil qualification of toy-pi-inprocess: FAIL" in out
    record = json.loads((report / "record.json").read_text())
    assert record["schema"] == "agrihil.qualification/1"
    assert record["verdict"] == "fail"
    assert record["dut"]["name"] == "toy-pi-inprocess"
    by_name = {m["name"]: m for m in record["measurements"]}
    assert by_name["flow.step.overshoot"]["outcome"] == "pass"
    assert by_name["flow.step.overshoot"]["high"] == 5.0
    assert by_name["flow.step.steady_state_error"]["outcome"] == "fail"
    assert len(record["runs"]) == 1                      # the second test reused the run
    run_dir = report / record["runs"][0]["dir"]
    assert (run_dir / "traces.npz").exists() and (run_dir / "bus.log").exists()
    assert by_name["flow.step.overshoot"]["run"] == record["runs"][0]["dir"]
    props = {p.get("name"): p.get("value")
             for p in ET.parse(tmp_path / "junit.xml").iter("property")}
    assert props["flow.step.overshoot[target_gps=23]"] == "1 % (pass)"
    # the summary says how many measurements a limit judged and how many were information
    # only (issue 43), in the record and on the console, counted from the measurements
    ms = record["measurements"]
    judged = sum(1 for m in ms if m["low"] is not None or m["high"] is not None)
    assert judged >= 2          # the two of the suite, limited by the profile
    assert record["summary"] == {"measurements": len(ms), "judged": judged,
                                 "information_only": len(ms) - judged}
    assert (f"judged: {judged} of {len(ms)} measurements had a limit; "
            f"{len(ms) - judged} information only (no limit)") in out


def test_plugin_passes_a_good_dut(tmp_path: Path) -> None:
    proc = _pytest(tmp_path, "--hil-dut", "toy-pi-inprocess.toml", "--hil-bus", "inline",
                   "--hil-report", str(tmp_path / "q"), "-k", "within or robust")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    record = json.loads((tmp_path / "q" / "record.json").read_text())
    assert record["verdict"] == "pass"
    suites = [m for m in record["measurements"] if not m["name"].startswith("bus.")]
    assert [m["outcome"] for m in suites] == ["pass", "pass"]
    # every run also carries its bus conformance (hil.conformance), and the toy DUT conforms
    bus = [m for m in record["measurements"] if m["name"].startswith("bus.")]
    assert {"bus.undeclared_frames", "bus.bootup.unexpected", "bus.share"} <= \
        {m["name"] for m in bus}
    assert {m["outcome"] for m in bus} == {"pass"}


@pytest.mark.parametrize(("suite", "message"), [
    (SUITE.replace('hil_suite("robustness")', 'hil_suite("nightly")'),
     "hil_suite marker needs one of fast, full, robustness, busload"),
    (SUITE.replace('hil_rig("sowing_depth")', 'hil_rig("sprayer")'),
     "hil_rig marker needs one rig name"),
])
def test_markers_are_validated_at_collection(tmp_path: Path, suite: str, message: str) -> None:
    proc = _pytest(tmp_path, "--hil-dut", "toy-pi-inprocess.toml", suite=suite)
    assert proc.returncode == 4
    assert message in proc.stdout + proc.stderr


def test_suites_need_a_dut(tmp_path: Path) -> None:
    proc = _pytest(tmp_path, "-k", "robust")
    assert proc.returncode != 0
    assert "HIL suites need a DUT: pytest --hil-dut PROFILE" in proc.stdout + proc.stderr


def test_bad_profile_is_a_usage_error(tmp_path: Path) -> None:
    (tmp_path / "broken.toml").write_text("[dut]\nname = 3\n")
    proc = _pytest(tmp_path, "--hil-dut", str(tmp_path / "broken.toml"))
    assert proc.returncode == 4
    assert "[dut.name] expected a string" in proc.stdout + proc.stderr


def test_unknown_measurement_name_fails_the_test(tmp_path: Path) -> None:
    suite = SUITE.replace('hil_measure("flow.step.overshoot", 2.0)',
                          'hil_measure("flow.step.overshot", 2.0)')
    proc = _pytest(tmp_path, "--hil-dut", "toy-pi-inprocess.toml", "--hil-suite",
                   "robustness", "--hil-report", str(tmp_path / "q"), suite=suite)
    assert proc.returncode == 1
    assert "measurement 'flow.step.overshot' is not in the catalogue" in proc.stdout


def test_the_record_names_the_rig_config_and_the_profile_overrides() -> None:
    """A test engineer sees which sensors the DUT was qualified with: the profile's [rig]
    overrides as dotted keys, and a hash of the whole config that differs with them."""
    from hil.dut.profile import load_profile
    from hil.pytest_plugin import _rig_config_identity
    from plant_emulators.fertilizer.rig import FertilizerRig

    root = Path(__file__).resolve().parents[2]
    sliding = load_profile(root / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml")
    block = load_profile(root / "dut_profiles" / "fertilizer-open-loop-daemon.toml")
    a = _rig_config_identity(FertilizerRig, sliding)
    b = _rig_config_identity(FertilizerRig, block)
    assert a["config_overrides"] == {"flow_sensor.mode": "sliding"}
    assert b["config_overrides"] == "none (the packaged config)"
    assert len(a["config_sha256"]) == 64 and a["config_sha256"] != b["config_sha256"]


# --- the console (issue 31.7) and the working directory (issue 31.9) ----------------------------


def _m(name: str, outcome: str = "pass", run: str = "runs/a") -> dict[str, object]:
    return {"name": name, "value": 1.0, "unit": "%", "low": None, "high": 5.0,
            "conditions": {}, "outcome": outcome, "marginal": False, "note": "why",
            "run": run}


def test_console_prints_control_measurements_and_one_conformance_line() -> None:
    from hil.console import test_lines

    ms = [_m("flow.step.overshoot"), *(_m(f"bus.share{i}") for i in range(13)),
          _m("bus.dlc_errors", run="runs/b")]
    lines = test_lines(ms)
    assert [text.split(" = ")[0] for text, _ in lines] == [
        "flow.step.overshoot", "bus conformance: 14 checks over 2 runs, all pass"]
    assert not any(bad for _, bad in lines)
    assert len(test_lines(ms, verbose=True)) == 2 + 14          # -vv: every check


def test_console_prints_every_failed_conformance_check() -> None:
    from hil.console import test_lines

    ms = [_m("flow.step.overshoot"), _m("bus.share"), _m("bus.heartbeat.period", "fail")]
    lines = test_lines(ms)
    assert lines[1] == ("bus conformance: 2 checks over 1 run, 1 failed", True)
    assert lines[2][0].startswith("  bus.heartbeat.period = 1 % FAIL") and lines[2][1]
    assert len(lines) == 3


@pytest.mark.parametrize("qualification", [True, False])
def test_a_qualification_leaves_no_benchmarks_directory(tmp_path: Path,
                                                        qualification: bool) -> None:
    """pytest-benchmark creates ``.benchmarks/`` in the working directory when it is loaded;
    a qualification (--hil-dut) blocks it. Without --hil-dut the directory appears, which
    shows the check can fail."""
    (tmp_path / "test_nothing.py").write_text("def test_nothing():\n    pass\n")
    hil = (["--hil-dut", str(REPO / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"),
            "--hil-bus", "inline", "--hil-report", str(tmp_path / "report")]
           if qualification else [])
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "--co", "-p",
                           "no:cacheprovider", "test_nothing.py", *hil],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert (tmp_path / ".benchmarks").exists() is not qualification


def test_verdict_of_a_session() -> None:
    """hil.qualification.verdict decides from what the session recorded, nothing else."""
    from hil.qualification.verdict import session_verdict

    ok = {"setup_error": "", "complete": True, "interrupted": False, "exitstatus": 0,
          "invalid_bench": {}, "dut_failures": {},
          "measurements": [{"outcome": "pass"}], "tests": [{"outcome": "passed"}]}
    assert session_verdict(**ok) == "pass"
    assert session_verdict(**{**ok, "measurements": [{"outcome": "fail"}]}) == "fail"
    assert session_verdict(**{**ok, "measurements": []}) == "error"
    assert session_verdict(**{**ok, "setup_error": "no ECU"}) == "error"
    assert session_verdict(**{**ok, "invalid_bench": {"t": "runs/t"}}) == "invalid-bench"
    assert session_verdict(**{**ok, "dut_failures": {"t": "stopped"}}) == "fail"
    assert session_verdict(**{**ok, "complete": False}) == "interrupted"
    assert session_verdict(**{**ok, "complete": False,
                              "tests": [{"outcome": "failed"}]}) == "fail"        # pytest -x
