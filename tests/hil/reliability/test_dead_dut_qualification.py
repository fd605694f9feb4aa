"""A DUT that stops is a failed qualification (exit 1), every affected measurement failed
with the reason "the DUT stopped at t = … s", and nothing in the suites raises (#21.3)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.helpers.hil_forkserver import HilForkServer

ROOT = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize(("how", "when"), [("exit0:20", "2.0"), ("segv:20", "2.0")])
def test_a_dut_that_dies_before_the_target_is_enabled_fails_the_qualification(
        dying_profile, tmp_path: Path, how: str, when: str, hil_forked: HilForkServer) -> None:
    out = tmp_path / "qual"
    # one test of each suite module's code (a step, a bench target, a robustness run): the
    # bench's other two targets would take the same path with a DUT started and dead again;
    # hil in a process of its own, forked by the hil_forked server (no start-up to pay)
    proc = hil_forked.run(
        ["qualify", str(dying_profile(how)), "--out", str(out),
         "-k", "test_flow_step[23] or test_saturation_recovery or test_bench_accuracy[1150-1]"],
        ROOT, timeout_s=600)
    assert proc.returncode == 1, proc.stdout[-3000:] + proc.stderr[-3000:]
    record = json.loads((out / "record.json").read_text())
    assert record["verdict"] == "fail" and record.get("complete", True)
    assert record["tests"] and all(t["outcome"] == "failed" for t in record["tests"])
    reason = f"the DUT stopped at t = {when} s"
    for test in record["tests"]:
        assert reason in test["message"], test
        assert "Traceback" not in test["message"] and "During handling" not in test["message"]
    # what the suites measured before their code gave up on the short traces, and what
    # they never got to, is failed with the reason
    names = {m["name"] for m in record["measurements"]}
    assert {"flow.step.response_time", "flow.step.overshoot", "flow.bench.accuracy",
            "flow.fault.saturation.recovery_time"} <= names, names
    for m in record["measurements"]:
        assert m["value"] is None and m["outcome"] in ("fail", "error")
        assert m["note"].startswith(reason), m
    assert all(run["error"].startswith("the DUT ") for run in record["runs"])
