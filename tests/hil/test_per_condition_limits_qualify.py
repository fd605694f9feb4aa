"""A per-condition limit, end to end: ``hil qualify`` judges each condition by its own limit.

The reference fertilizer controller's step tests at 23, 34 and 44 g/s (inline bus, ~10 s),
with a profile whose response-time limit is tighter at 34 g/s than the reference meets (it
reads ~0.5 s at every rate): that condition fails, the two others pass under the entry's own
1.5 s, and the record, the console and the report say which limit applied.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PROFILE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
ENTRY = '"flow.step.response_time" = { high = 1.5, marginal = 0.1 }'
PER_CONDITION = ('"flow.step.response_time" = { high = 1.5, marginal = 0.1, when = [ '
                 '{ target_gps = 34, high = 0.3 } ] }')


def test_a_per_condition_limit_fails_its_condition_only(tmp_path: Path) -> None:
    text = PROFILE.read_text(encoding="utf-8")
    assert text.count(ENTRY) == 1
    profile = tmp_path / PROFILE.name
    profile.write_text(text.replace(ENTRY, PER_CONDITION), encoding="utf-8")
    done = subprocess.run(
        [sys.executable, "-m", "hil", "qualify", str(profile), "--bus", "inline",
         "--out", str(tmp_path / "q"), "-k", "test_flow_step"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600)
    out = done.stdout[-3000:] + done.stderr[-3000:]
    assert done.returncode == 1, out
    record = json.loads((tmp_path / "q" / "record.json").read_text(encoding="utf-8"))
    assert record["verdict"] == "fail"
    steps = {m["conditions"]["target_gps"]: m for m in record["measurements"]
             if m["name"] == "flow.step.response_time"}
    assert sorted(steps) == [23, 34, 44]
    assert steps[34]["outcome"] == "fail" and steps[34]["high"] == 0.3
    assert steps[34]["limit_source"] == "profile (target_gps=34)"
    assert steps[34]["value"] > 0.3
    for rate in (23, 44):
        assert steps[rate]["outcome"] == "pass", steps[rate]
        assert (steps[rate]["high"], steps[rate]["limit_source"]) == (1.5, "profile")
    # the only failure of the qualification is that one
    failed = [m for m in record["measurements"] if m["outcome"] in ("fail", "error")]
    assert failed == [steps[34]]
    assert "flow.step.response_time[target_gps=34]" in out and "FAIL (limit <= 0.3)" in out
    assert record["limits"]["flow.step.response_time"]["when"] == [
        {"conditions": {"target_gps": 34}, "low": None, "high": 0.3}]
    report = (tmp_path / "q" / "report.html").read_text(encoding="utf-8")
    assert "per condition (profile: target_gps=34)" in report
    # the gate judges each condition by its own limit and says nothing of the entry's band
    summary = tmp_path / "gate.md"
    gate = subprocess.run([sys.executable, "-m", "hil", "gate", str(tmp_path / "q"
                                                                     / "record.json"),
                           "--summary", str(summary)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert gate.returncode == 1, gate.stdout + gate.stderr
    assert "limits table" not in summary.read_text(encoding="utf-8") + gate.stdout
