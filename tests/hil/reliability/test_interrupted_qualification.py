"""An interrupted qualification is never a pass (issue #22.1).

A real ``hil qualify`` subprocess gets two SIGINTs 200 ms apart (or SIGTERM then SIGINT) at
several moments; whatever moment, ``record.json`` must be valid, its verdict never ``pass``,
it must say which tests/runs completed, and ``hil gate`` must refuse it (exit 2).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil.gate import load_record
from tests.fuzz.cli import Outcome, run_cli
from tests.helpers.hil_forkserver import HilForkServer

ROOT = Path(__file__).resolve().parents[3]
PROFILE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
HIL = [sys.executable, "-m", "hil"]
#: 9 tests on the inline bus (3-15 s, by the machine's load)
SELECTION = "test_flow_step or test_bench_accuracy or test_field_accuracy"


def _qualify(out: Path) -> subprocess.Popen[str]:
    return subprocess.Popen([*HIL, "qualify", str(PROFILE), "--bus", "inline", "--out",
                             str(out), "-k", SELECTION],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})


def _wait_for_moment(proc: subprocess.Popen[str], moment: str) -> str:
    """Block until the qualification reaches ``moment``; the output read so far."""
    if moment == "start":
        time.sleep(0.3)                      # Python still starting, or options being checked
        return ""
    want = {"collected": "collected", "first-test": "PASSED", "fourth-test": "PASSED"}[moment]
    needed = 4 if moment == "fourth-test" else 1
    seen, text = 0, ""
    assert proc.stdout is not None
    while seen < needed:
        line = proc.stdout.readline()
        assert line, f"the qualification ended before {moment}:\n{text}"
        text += line
        seen += want in line
    return text


def _gate(record: Path) -> Outcome:
    """``hil gate RECORD`` in this process (its exit status and output are the command's;
    a new interpreter for each, ~0.9 s of CPU, would only add its imports)."""
    return run_cli("gate", str(record))


def _passing_record(out: Path) -> None:
    """A previous qualification's passing record in --out, as a CI workspace would hold."""
    out.mkdir(parents=True)
    (out / "record.json").write_text(json.dumps({
        "schema": "agrihil.qualification/1", "run_id": "old", "verdict": "pass",
        "dut": {"name": "fertilizer-piecewise-pid-daemon"},
        "measurements": [{"name": "flow.step.overshoot", "value": 1.0, "unit": "%",
                          "low": None, "high": 5.0, "conditions": {}, "outcome": "pass"}]}))
    assert _gate(out / "record.json").code == 0


@pytest.mark.parametrize("first_signal", [
    signal.SIGINT, pytest.param(signal.SIGTERM, marks=pytest.mark.slow)])
@pytest.mark.parametrize("moment", ["start", "collected", "first-test", "fourth-test"])
def test_interrupt_at_any_moment_leaves_a_record_no_gate_passes(
        tmp_path: Path, moment: str, first_signal: int) -> None:
    out = tmp_path / "qual"
    _passing_record(out)
    proc = _qualify(out)
    before = _wait_for_moment(proc, moment)
    proc.send_signal(first_signal)
    time.sleep(0.2)
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    output, _ = proc.communicate(timeout=120)
    output = before + output
    record_path = out / "record.json"
    record = json.loads(record_path.read_text())       # valid JSON, whole
    if record["run_id"] == "old":
        # interrupted while Python was still starting or the options were being checked
        # (before the qualification began): --out is untouched and hil says so
        assert moment == "start", output
        assert proc.returncode in (130, -first_signal), output
        assert proc.returncode < 0 or "before the" in output, output
        return
    assert proc.returncode in (130, 2), output
    assert "Traceback" not in output, output
    load_record(record_path)                             # and a valid record for the gate
    assert record["verdict"] == "interrupted", output
    assert record["complete"] is False
    assert isinstance(record["runs"], list) and isinstance(record["tests"], list)
    assert record["tests_completed"] == len(record["tests"]) or record["tests_planned"] is None
    gate = _gate(record_path)
    assert gate.code == 2, gate.stdout + gate.stderr
    assert "interrupted" in gate.stderr and len(gate.stderr.strip().splitlines()) == 1
    # the previous record is kept, and nothing half-written or staged is left behind
    assert json.loads((out / "record.previous.json").read_text())["run_id"] == "old"
    assert not [p for p in out.iterdir() if p.name.startswith(".")], list(out.iterdir())


def test_a_finished_qualification_replaces_the_previous_one(tmp_path: Path,
                                                            hil_forked: HilForkServer) -> None:
    out = tmp_path / "qual"
    _passing_record(out)
    (out / "runs").mkdir()
    (out / "runs" / "old-run").mkdir()
    proc = hil_forked.run(["qualify", str(PROFILE), "--bus", "inline", "--out", str(out),
                           "-k", "test_flow_step and 23"], ROOT, timeout_s=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # the console: each measurement as it is judged, only this rig's suites (no SKIPPED lines
    # for the other rig), and the summary
    assert "    flow.step.overshoot[target_gps=23] = " in proc.stdout
    assert "sowing_depth" not in proc.stdout and "SKIPPED" not in proc.stdout
    assert re.search(r"measurements: \d+ = \d+ pass", proc.stdout), proc.stdout[-2000:]
    record = json.loads((out / "record.json").read_text())
    assert record["verdict"] == "pass" and "complete" not in record   # complete: no marks
    assert len(record["tests"]) == 1
    assert not (out / "runs" / "old-run").exists()
    assert all((out / run["dir"]).is_dir() for run in record["runs"])
    assert oct((out / "record.json").stat().st_mode & 0o777) != oct(0o600)


def test_a_killed_qualification_leaves_an_interrupted_record(tmp_path: Path) -> None:
    out = tmp_path / "qual"
    _passing_record(out)
    proc = _qualify(out)
    _wait_for_moment(proc, "first-test")
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)
    record = json.loads((out / "record.json").read_text())
    assert record["verdict"] == "interrupted"
    assert _gate(out / "record.json").code == 2


def test_the_gate_refuses_any_incomplete_record_that_is_not_a_fail(tmp_path: Path) -> None:
    from hil.gate import parse_record

    base = {"schema": "agrihil.qualification/1", "run_id": "r", "dut": {"name": "d"},
            "measurements": [], "tests_planned": 18, "tests_completed": 13}
    refused = [("interrupted", True), ("interrupted", False), ("pass", False),
               ("error", False)]
    for verdict, complete in refused:
        rec = parse_record({**base, "verdict": verdict, "complete": complete}, path="r.json")
        reason = rec.incomplete_reason()
        assert reason and "after 13 of 18 tests" in reason, (verdict, complete)
    for verdict, complete in [("fail", False), ("pass", True), ("error", True)]:
        rec = parse_record({**base, "verdict": verdict, "complete": complete}, path="r.json")
        assert rec.incomplete_reason() is None
    old = parse_record({k: v for k, v in {**base, "verdict": "pass"}.items()
                        if not k.startswith("tests_")}, path="r.json")
    assert old.complete and old.incomplete_reason() is None   # records from before
