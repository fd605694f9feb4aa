"""Whatever is wrong with a run, the page says so and is still written."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.clock.base import TimingHealth, TimingLimits
from hil.report import load_qualification, write_html
from hil.report.plots_runs import plot_run
from hil.report.rundata import load_run, rig_plot_groups
from plant_emulators.fertilizer.rig import FertilizerRig


def _only(record: dict[str, Any], *dirs: str) -> dict[str, Any]:
    """The record restricted to some runs (fewer plots: faster tests)."""
    record["runs"] = [r for r in record["runs"] if r["dir"] in dirs]
    record["measurements"] = [m for m in record["measurements"] if m["run"] in dirs]
    return record


@pytest.fixture
def fresh_plot_groups() -> Any:
    rig_plot_groups.cache_clear()
    yield
    rig_plot_groups.cache_clear()


def test_unknown_trace_names_become_notes(make_qual_dir: Callable[..., Path],
                                          base_record: dict[str, Any],
                                          monkeypatch: pytest.MonkeyPatch,
                                          fresh_plot_groups: None) -> None:
    groups = [("flow, row 1 [g/s]", ["target_flow_row_gps", "no_such_trace_gps"])]
    monkeypatch.setattr(FertilizerRig, "plot_groups", groups)
    qual_dir = make_qual_dir(_only(base_record, "runs/test_step-23"))
    html = write_html(qual_dir).read_text()
    assert "trace &#x27;no_such_trace_gps&#x27; (plot group &#x27;flow, row 1 [g/s]&#x27;) is " \
           "not in runs/test_step-23/traces.npz" in html
    assert 'alt="step run runs/test_step-23' in html   # what exists is still plotted


def test_no_known_trace_and_unknown_rig(make_qual_dir: Callable[..., Path],
                                        base_record: dict[str, Any],
                                        monkeypatch: pytest.MonkeyPatch,
                                        fresh_plot_groups: None) -> None:
    monkeypatch.setattr(FertilizerRig, "plot_groups", [("x", ["nothing_here"])])
    qual_dir = make_qual_dir(_only(base_record, "runs/test_step-23"))
    html = write_html(qual_dir).read_text()
    assert "none of the main plot group&#x27;s traces is in traces.npz" in html
    rig_plot_groups.cache_clear()
    record = (qual_dir / "record.json").read_text().replace('"fertilizer"', '"no-such-rig"')
    (qual_dir / "record.json").write_text(record)
    (qual_dir / "runs/test_step-23/record.json").write_text("{}")
    html = write_html(qual_dir).read_text()
    assert "rig &#x27;no-such-rig&#x27; cannot be loaded" in html


def test_broken_run_files_become_notes(make_qual_dir: Callable[..., Path],
                                       base_record: dict[str, Any]) -> None:
    qual_dir = make_qual_dir(_only(base_record, "runs/test_step-23"))
    run = qual_dir / "runs/test_step-23"
    (run / "traces.npz").write_bytes(b"not a zip")
    (run / "record.json").write_text("[")
    base_record["runs"].append({"dir": "runs/gone", "scenario": "x", "verdict": "error",
                                "error": "BusError: the interface went down"})
    html = write_html(make_qual_dir(base_record, name="q2")).read_text()
    assert "runs/gone: run directory missing" in html
    assert "BusError: the interface went down" in html[html.index('id="errors"'):]
    html = write_html(qual_dir).read_text()
    assert "runs/test_step-23/traces.npz unreadable" in html
    assert "runs/test_step-23/record.json unreadable" in html


def test_odd_values_and_an_empty_record(tmp_path: Path) -> None:
    (tmp_path / "record.json").write_text('{"schema": "agrihil.qualification/1", '
                                          '"verdict": "mystery", "measurements": [{'
                                          '"name": "<b>x</b>", "value": "n/a", "low": "1", '
                                          '"conditions": [1], "run": "../../etc"}], '
                                          '"tests": [{}], "runs": [{}]}')
    html = write_html(tmp_path).read_text()
    assert "MYSTERY" in html and "&lt;b&gt;x&lt;/b&gt;" in html and "<b>x</b>" not in html
    assert 'href="../' not in html


def test_step_run_marks_its_response_time(qual_page: tuple[Path, str]) -> None:
    qual_dir, _ = qual_page
    qual = load_qualification(qual_dir)
    step = load_run(qual, next(r for r in qual.runs if r.dir == "runs/test_step-23"))
    plot = plot_run(step)
    assert plot.kind == "step" and plot.image is not None
    assert plot.notes == []   # the response time found its step (3 s in the trace)


def test_realtime_timing_gets_a_histogram(make_qual_dir: Callable[..., Path],
                                          base_record: dict[str, Any]) -> None:
    lateness = np.random.default_rng(1).lognormal(np.log(5e-6), 1.0, 5000)
    timing = TimingHealth.from_lateness(lateness, period_s=1e-3, scheduler="SCHED_FIFO",
                                        limits=TimingLimits(p99_lateness_s=1e-5),
                                        miss_threshold_s=5e-4, stall_threshold_s=0.05)
    record = _only(base_record)
    record.update(verdict="invalid-bench", clock="realtime", timing=timing.to_dict())
    html = write_html(make_qual_dir(record)).read_text()
    assert 'class="verdict-word">INVALID BENCH<' in html
    assert "bench timing out of bounds: p99 lateness" in html
    assert 'alt="timing histogram of tick lateness"' in html
    assert "lockstep: virtual time" not in html


def test_malformed_arrays_and_timing_become_notes(make_qual_dir: Callable[..., Path],
                                                  base_record: dict[str, Any]) -> None:
    record = _only(base_record, "runs/test_step-23")
    record["timing"] = {"mode": "realtime", "valid": False, "invalid_reasons": "one string",
                        "histogram_edges_s": [0.0, 1e-6, 2e-6], "histogram_counts": ["x", 1]}
    qual_dir = make_qual_dir(record)
    units = json.dumps({"time_s": "s", "target_flow_row_gps": "g/s"})
    np.savez_compressed(qual_dir / "runs/test_step-23/traces.npz", __units__=np.array(units),
                        time_s=np.arange(10.0), target_flow_row_gps=np.arange(5.0))
    html = write_html(qual_dir).read_text()
    assert "runs/test_step-23: plot failed (ValueError" in html
    assert "timing histogram failed (ValueError" in html
    assert "<li>one string</li>" in html
