"""The CI summary leads with the verdict, then what needs a look (failures, regressions,
marginal values), then the control measurements; bus conformance is one line per run unless
one of its checks needs a look (issue 31 item 6)."""

from __future__ import annotations

import json
from pathlib import Path

from hil.gate import compare, load_baseline, parse_record, render_markdown
from hil.measurements import Measurement

from .records import record

ROOT = Path(__file__).resolve().parents[3]
BASELINE = ROOT / "ci/baselines/fertilizer-piecewise-pid-firmware.json"
BUS_CHECKS = ("bus.share", "bus.undeclared_frames", "bus.dlc_errors")


def _bus(run: str, *, bad: str = "") -> list[Measurement]:
    return [Measurement(name, 2.0 if name == bad else 0.0, "frames", high=1.0,
                        conditions={"node": "FlowController", "run": run})
            for name in BUS_CHECKS]


def _sections(markdown: str) -> list[str]:
    return [line for line in markdown.splitlines() if line.startswith("#")]


def test_verdict_then_what_needs_a_look_then_control_then_one_bus_line_per_run() -> None:
    ms = [Measurement("flow.step.overshoot", 12.0, "%", high=10.0,
                      conditions={"target_gps": 23}),
          Measurement("flow.bench.accuracy", 97.0, "%", low=90.0,
                      conditions={"target_g": 1700}),
          *_bus("bench-step-23"), *_bus("field-6kmh", bad="bus.share"), *_bus("bench-10g")]
    md = render_markdown(compare(parse_record(record(ms), path="r.json"), None))
    lines = md.splitlines()
    assert lines[0].startswith("### ❌ agrihil gate: FAIL")
    heads = _sections(md)
    assert [h.split(" (")[0] for h in heads[1:]] == [
        "#### Needs a look", "#### Control measurements", "#### Bus conformance"]
    look = md.split("#### Needs a look")[1].split("####")[0]
    assert "`flow.step.overshoot`" in look and "`bus.share`" in look   # the failing bus check
    assert "flow.bench.accuracy" not in look
    control = md.split("#### Control measurements")[1].split("####")[0]
    assert "`flow.bench.accuracy`" in control and "bus." not in control
    bus = md.split("#### Bus conformance")[1].split("Notes:")[0]
    runs = [line for line in bus.splitlines() if line.startswith("- ")]
    assert len(runs) == 3, bus                                   # one line per run
    assert any("field-6kmh" in r and "1 FAIL" in r and "see above" in r for r in runs), runs
    assert not [line for line in bus.splitlines() if line.startswith("| `bus.")]


def test_a_real_passing_qualification_fits_on_a_ci_page() -> None:
    """The fertilizer baseline as a record: a pass with its bus rows folded into one line per
    run (the old layout printed a table row per measurement, bus rows first)."""
    entries = json.loads(BASELINE.read_text())["measurements"]
    ms = [Measurement(e["name"], e["value"], e["unit"], low=e["low"], high=e["high"],
                      conditions=e["conditions"]) for e in entries.values()]
    result = compare(parse_record(record(ms), path="r.json"), load_baseline(BASELINE))
    md = render_markdown(result)
    lines = md.splitlines()
    control = [m for m in ms if not m.name.startswith("bus.")]
    runs = {m.conditions["run"] for m in ms if m.name.startswith("bus.")}
    assert len(lines) <= len(control) + len(runs) + 25, len(lines)
    first_table_row = next(line for line in lines if line.startswith("| `"))
    assert "`bus." not in first_table_row
