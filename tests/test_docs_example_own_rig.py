"""The worked example of a rig of your own (docs/guide/own-rig.md, docs/examples/
own-rig-motor-meter): an FMU nobody here wrote the model of (Reference-FMUs StateSpace, built
from its sources with CMake), a DBC of its own, a controller of a few lines that qualifies and
a must-fail one that the suites fail. Run as the page says, in a copy of the example, each
``hil`` command in a process of its own with the example on ``PYTHONPATH``.

The default run builds the FMU, checks the rig file and runs both controllers' step through
the step suite's own metric (~10 s); the qualifications the page shows (two ``hil qualify``
of the fast suite, ~10 s of CPU each) also run as the page's commands in
tests/test_docs_examples.py, so here they are ``slow``, with the robustness suite."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.hil.ownrig.example import example_copy

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "guide" / "own-rig.md"


@pytest.fixture(scope="module")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example copied beside a scratch root, its FMU built: the copy's directory."""
    rig_file = example_copy(tmp_path_factory.mktemp("docs-own-rig") / "motor-meter")
    return rig_file.parent


def hil(example: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(example), str(REPO)])}
    env.pop("AGRIHIL_RIG_FILES", None)
    return subprocess.run([sys.executable, "-m", "hil", *argv], cwd=example.parent, env=env,
                          capture_output=True, text=True, timeout=600)


def qualify(example: Path, profile: str, suites: str, out: str) -> tuple[int, dict]:
    result = hil(example, "qualify", f"motor-meter/{profile}", "--rig",
                 "motor-meter/motor-meter.rig.toml", "--bus", "inline", "--suite", suites,
                 "--out", out)
    assert result.returncode in (0, 1), result.stderr[-3000:]
    return result.returncode, json.loads((example.parent / out / "record.json").read_text())


def failed(record: dict) -> set[str]:
    return {m["name"] for m in record["measurements"] if m["outcome"] in ("fail", "error")}


def test_the_page_runs_these_commands() -> None:
    text = PAGE.read_text()
    for line in ("hil rig check motor-meter/motor-meter.rig.toml",
                 "hil qualify motor-meter/pi-speed.toml --rig motor-meter/motor-meter.rig.toml "
                 "--bus inline --suite fast --out qual-pi",
                 "hil qualify motor-meter/open-loop-speed.toml --rig "
                 "motor-meter/motor-meter.rig.toml --bus inline --suite fast --out qual-open"):
        assert line in text


def test_worked_example_checks_and_steps(example: Path, tmp_path: Path) -> None:
    """The rig file checks; on the step suite's first scenario, judged as the suite judges it
    against the rig file's limits, the PI controller meets them and the open loop does not."""
    check = hil(example, "rig", "check", "motor-meter/motor-meter.rig.toml")
    assert check.returncode == 0, check.stderr
    assert "fmpy validation: no problems" in check.stdout
    sys.path.insert(0, str(example))
    try:
        import motor_controller

        from hil.dut.inprocess import InProcessDut
        from hil.metrics import step_response
        from hil.ownrig.rig import rig_class
        from hil.ownrig.scenarios import step_scenario
        from hil.rig import RunOptions, run_scenario

        rig = rig_class(example / "motor-meter.rig.toml")
        c = rig.plan().controlled["speed"]
        limits = c.spec.limits
        scenario = step_scenario(rig, c, 0)
        for cls, good in ((motor_controller.PiSpeed, True),
                          (motor_controller.OpenLoopSpeed, False)):
            result = run_scenario(rig, scenario, InProcessDut(cls(), cls),
                                  RunOptions(out_dir=tmp_path / cls.name, bus="inline"))
            traces, _ = result.traces()
            target = c.spec.steps[0]
            m = step_response(traces["time_s"], traces["true_y_1"], t0=c.spec.step_at_s,
                              target=target, y0=c.spec.start, band=c.band / target,
                              steady_window_s=c.spec.steady_window_s)
            error = abs(m.steady_state_value - target)
            meets = (m.response_time_s <= limits.response_time_s
                     and error <= limits.steady_state_error
                     and m.overshoot_pct <= limits.overshoot_pct)
            assert meets is good, (cls.name, m.response_time_s, error, m.overshoot_pct)
    finally:
        sys.path.remove(str(example))
        sys.modules.pop("motor_controller", None)


@pytest.mark.slow
def test_worked_example_qualifies_and_the_must_fail_fails(example: Path) -> None:
    code, record = qualify(example, "pi-speed.toml", "fast", "qual-pi")
    assert code == 0 and record["verdict"] == "pass", failed(record)
    ours = [m for m in record["measurements"] if m["name"].startswith("motor_meter.speed.")]
    assert {m["name"].split(".", 2)[2] for m in ours} >= {
        "step.response_time", "step.overshoot", "step.steady_state_error",
        "step.sensed_steady_state_error", "tracking.rms_error"}
    judged = [m for m in ours if m["name"].endswith("step.response_time")]
    assert judged and all(m["limit_source"] == "rig file motor-meter.rig.toml "
                          "[controlled.speed.limits.response_time_s]" for m in judged)
    code, record = qualify(example, "open-loop-speed.toml", "fast", "qual-open")
    assert code == 1 and record["verdict"] == "fail"
    assert {"motor_meter.speed.step.steady_state_error",
            "motor_meter.speed.tracking.rms_error"} <= failed(record)


@pytest.mark.slow
def test_worked_example_robustness(example: Path) -> None:
    """Both suites: the PI controller passes every measurement, the open loop fails the
    robustness ones too (it never comes back to the set-point after a fault)."""
    code, record = qualify(example, "pi-speed.toml", "fast,robustness", "qual-pi-all")
    assert code == 0, failed(record)
    code, record = qualify(example, "open-loop-speed.toml", "fast,robustness", "qual-open-all")
    assert code == 1
    assert {"motor_meter.speed.fault.sensor_dropout.recovery_time",
            "motor_meter.speed.fault.restart.recovery_time"} <= failed(record)
