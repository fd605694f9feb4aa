"""A qualification directory for the report tests: a synthetic ``record.json`` over two real
short runs (a fertilizer step and a short field run, lockstep on the inline bus), one run
whose directory holds only an errored record, and one whose traces are missing."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest

from hil.dut import InProcessDut
from hil.rig import Event, RunOptions, Scenario, run_scenario
from plant_emulators.fertilizer.controllers import PiFlowController
from plant_emulators.fertilizer.rig import FertilizerRig

STEP_RUN = "runs/test_step-23"
FIELD_RUN = "runs/test_field-6kmh"
ERROR_RUN = "runs/test_restart"
NO_TRACES_RUN = "runs/test_fault-sensor-silent"
STDERR_TAIL = "panic: flow table <corrupt> & exiting"


def _step() -> Scenario:
    return Scenario(name="bench-step-23-short", description="", rig="fertilizer",
                    duration_s=8.0, seed=23,
                    initial={"terminal_mode": 1.0, "enable": 0.0, "target_flow_gps": 23.0},
                    events=(Event(at_s=3.0, set={"enable": 1.0}),))


def _field() -> Scenario:
    return Scenario(name="field-6kmh-short", description="", rig="fertilizer", duration_s=7.0,
                    seed=6, initial={"terminal_mode": 0.0, "enable": 0.0,
                                     "rate_kg_per_hm2": 200.0, "width_m": 3.0},
                    speed_profile=((0.0, 1.6667), (7.0, 1.6667)),
                    events=(Event(at_s=3.0, set={"enable": 1.0}),))


@pytest.fixture(scope="session")
def real_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two real run directories, made once per session (about a second)."""
    root = tmp_path_factory.mktemp("report-runs")
    out = {}
    for key, scenario in (("step", _step()), ("field", _field())):
        result = run_scenario(FertilizerRig, scenario, InProcessDut(PiFlowController()),
                              RunOptions(out_dir=root / key, bus="inline", clock="lockstep"))
        out[key] = result.out_dir
    return out


def measurement(name: str, value: float | None, unit: str, *, low: float | None = None,
                high: float | None = None, outcome: str = "pass", marginal: bool = False,
                run: str = STEP_RUN, test: str = "test_suites/fertilizer/test_step.py::"
                "test_step[23]", note: str = "", **conditions: Any) -> dict[str, Any]:
    return {"name": name, "value": value, "unit": unit, "low": low, "high": high,
            "conditions": conditions, "outcome": outcome, "marginal": marginal, "note": note,
            "test": test, "run": run}


def synthetic_record(**overrides: Any) -> dict[str, Any]:
    field_test = "test_suites/fertilizer/test_field.py::test_field[6]"
    record: dict[str, Any] = {
        "schema": "agrihil.qualification/1",
        "run_id": "3f2a9c1b7d10",
        "started_at": "2026-11-22T10:00:00+00:00",
        "wall_s": 41.2,
        "verdict": "fail",
        "dut": {"name": "fertilizer-pi <test>", "version": "1.0.0", "build_id": "abc123",
                "kind": "in-process", "rig": "fertilizer", "controller": "pi",
                "profile": "dut_profiles/fertilizer-pi.toml", "profile_sha256": "9" * 64},
        "rig": {"name": "fertilizer", "config_sha256": "e" * 64},
        "bus": "inline", "clock": "lockstep", "seed": 1, "suites": ["fast"],
        "versions": {"agrihil": "0.1.0", "python": "3.11.7"},
        "limits": {"flow.step.response_time": {"low": None, "high": 1.5, "unit": "s"},
                   "flow.restart.recovery_time": {"low": None, "high": 3.0, "unit": "s"}},
        "measurements": [
            measurement("flow.step.response_time", 1.12, "s", high=1.5, target_gps=23,
                        sensor="sliding"),
            measurement("flow.step.overshoot", 4.9, "%", high=5.0, marginal=True,
                        target_gps=23),
            measurement("flow.step.steady_state_error", 7.5, "%", high=5.0, outcome="fail",
                        target_gps=23),
            measurement("flow.field.accuracy", 97.1, "%", low=95.0, run=FIELD_RUN,
                        test=field_test, speed_kmh=6),
            measurement("flow.field.accuracy", 93.0, "%", low=95.0, outcome="fail",
                        run=NO_TRACES_RUN, test=field_test, speed_kmh=8),
            measurement("flow.fault.sensor_dropout.accuracy", None, "%", low=90.0,
                        outcome="error", run=NO_TRACES_RUN,
                        test="test_suites/fertilizer/test_faults.py::test_dropout",
                        note="no usable flow signal", row=2),
            measurement("flow.step.peak_command", 3.1, "V", outcome="info", target_gps=23),
        ],
        "tests": [
            {"nodeid": "test_suites/fertilizer/test_step.py::test_step[23]",
             "outcome": "failed", "duration_s": 0.8, "message": "steady-state error 7.5 % > 5 %"},
            {"nodeid": "test_suites/fertilizer/test_field.py::test_field[6]",
             "outcome": "passed", "duration_s": 1.4, "message": ""},
            {"nodeid": "test_suites/fertilizer/test_restart.py::test_restart",
             "outcome": "error", "duration_s": 0.1, "message": "DutError: the DUT exited"},
        ],
        "runs": [
            {"dir": STEP_RUN, "scenario": "bench-step-23", "verdict": "fail", "sim_s": 8.0,
             "wall_s": 0.2},
            {"dir": FIELD_RUN, "scenario": "field-6kmh", "verdict": "pass", "sim_s": 7.0,
             "wall_s": 0.2},
            {"dir": ERROR_RUN, "scenario": "bench-step-34", "verdict": "error", "sim_s": 1.2,
             "wall_s": 0.1},
            {"dir": NO_TRACES_RUN, "scenario": "fault-sensor-silent", "verdict": "fail",
             "sim_s": 30.0, "wall_s": 0.5},
        ],
        "timing": {"mode": "lockstep", "period_s": 0.001, "ticks": 8000, "valid": True},
    }
    record.update(overrides)
    return record


def build_qual_dir(root: Path, real_runs: dict[str, Path],
                   record: dict[str, Any] | None = None) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    shutil.copytree(real_runs["step"], root / STEP_RUN)
    shutil.copytree(real_runs["field"], root / FIELD_RUN)
    error_run = root / ERROR_RUN
    error_run.mkdir(parents=True)
    (error_run / "record.json").write_text(json.dumps({
        "verdict": "error", "rig": "fertilizer", "scenario": "bench-step-34",
        "error": "DutError: the DUT process exited with status 3",
        "dut": {"name": "fertilizer-pi", "failure": "exited with status 3",
                "exit": "status 3", "stderr_tail": STDERR_TAIL}}))
    no_traces = root / NO_TRACES_RUN
    shutil.copytree(real_runs["step"], no_traces)
    (no_traces / "traces.npz").unlink()
    (root / "record.json").write_text(json.dumps(record or synthetic_record(), indent=1))
    return root


@pytest.fixture(scope="session")
def qual_page(tmp_path_factory: pytest.TempPathFactory,
              real_runs: dict[str, Path]) -> tuple[Path, str]:
    """The synthetic qualification directory with its report written once: (dir, html)."""
    from hil.report import write_html

    qual_dir = build_qual_dir(tmp_path_factory.mktemp("qual"), real_runs)
    page = write_html(qual_dir)
    return qual_dir, page.read_text(encoding="utf-8")


@pytest.fixture
def base_record() -> dict[str, Any]:
    """The synthetic record, to modify before :func:`make_qual_dir`."""
    return synthetic_record()


@pytest.fixture
def make_qual_dir(tmp_path: Path, real_runs: dict[str, Path]) -> Callable[..., Path]:
    """A fresh qualification directory (the same runs) holding the given record."""
    def make(record: dict[str, Any] | None = None, name: str = "qual") -> Path:
        return build_qual_dir(tmp_path / name, real_runs, record)

    return make


class Page(HTMLParser):
    """What the tests look at in a report: tag balance, tables by class, images, links."""

    VOID = frozenset({"meta", "img", "br", "hr", "link", "input", "col", "wbr", "source"})

    def __init__(self, text: str) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.problems: list[str] = []
        self.images: list[dict[str, str]] = []
        self.hrefs: list[str] = []
        self.ids: list[str] = []
        #: table class -> rows -> (row class, [cell texts])
        self.tables: dict[str, list[tuple[str, list[str]]]] = {}
        self._table: str | None = None
        self._row: tuple[str, list[str]] | None = None
        self._cell: list[str] | None = None
        self.text: list[str] = []
        self.feed(text)
        self.close()
        if self.stack:
            self.problems.append(f"unclosed: {self.stack}")

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        if "id" in a:
            self.ids.append(a["id"])
        if tag == "img":
            self.images.append(a)
        if tag == "a" and "href" in a:
            self.hrefs.append(a["href"])
        if tag == "table":
            self._table = a.get("class", "")
            self.tables.setdefault(self._table, [])
        if tag == "tr" and self._table is not None:
            self._row = (a.get("class", ""), [])
        if tag in ("td", "th") and self._row is not None:
            self._cell = []
        elif tag in ("div", "br", "p", "pre") and self._cell is not None:
            self._cell.append(" ")   # a block inside a cell: a word boundary
        if tag not in self.VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag: str) -> None:
        if tag in self.VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.problems.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
            return
        self.stack.pop()
        if tag in ("td", "th") and self._row is not None and self._cell is not None:
            self._row[1].append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "tr" and self._row is not None and self._table is not None:
            self.tables[self._table].append(self._row)
            self._row = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data: str) -> None:
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)


@pytest.fixture(scope="session")
def parse() -> Callable[[str], Page]:
    return Page
