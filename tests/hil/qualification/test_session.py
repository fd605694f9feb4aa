"""The qualification session outside pytest: measurements judged and kept, the record made
(no rig is run), and the pytest plugin a thin layer over the package (issue 43)."""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

import pytest

from hil.dut.profile import load_profile
from hil.errors import ConfigError
from hil.qualification.record import Completeness
from hil.qualification.session import QualificationSession
from hil.rig import RunResult

REPO = Path(__file__).resolve().parents[3]
FERTILIZER = REPO / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
#: the record's top-level keys for a complete session (docs/reference/record-format.md)
RECORD_KEYS = {"schema", "run_id", "started_at", "wall_s", "verdict", "dut", "rig", "bus",
               "clock", "seed", "suites", "versions", "limits", "summary", "measurements",
               "tests", "runs", "timing"}


def _session(tmp_path: Path) -> QualificationSession:
    return QualificationSession(profile=load_profile(FERTILIZER), bus="inline",
                                clock="lockstep", report_dir=tmp_path / "q", seed=None)


def test_a_measurement_is_judged_kept_by_test_and_counted_in_the_summary(
        tmp_path: Path) -> None:
    session = _session(tmp_path)
    limit = session.profile.limit("flow.step.response_time")
    assert limit is not None and limit.high is not None
    good = session.measure("t::a", "flow.step.response_time", limit.high / 2,
                           conditions={"target_gps": 23})
    bad = session.measure("t::b", "flow.step.response_time", limit.high * 2,
                          conditions={"target_gps": 23})
    assert (good.outcome.value, bad.outcome.value) == ("pass", "fail")
    assert [m["test"] for m in session.measurements] == ["t::a", "t::b"]
    assert session.measurements_of("t::b") == [bad]
    record = session.record(0)
    assert set(record) == RECORD_KEYS
    judged = sum(1 for m in record["measurements"]
                 if m["low"] is not None or m["high"] is not None)
    assert record["summary"] == {"measurements": 2, "judged": judged,
                                 "information_only": 2 - judged}
    assert judged == 2 and record["verdict"] == "fail"


def test_an_unknown_measurement_is_an_error_naming_the_test(tmp_path: Path) -> None:
    message = "t::a: measurement 'flow.step.overshot' is not in the catalogue"
    with pytest.raises(ConfigError, match=re.escape(message)):
        _session(tmp_path).measure("t::a", "flow.step.overshot", 1.0)


def test_a_value_from_a_run_whose_dut_stopped_is_failed_with_the_reason(
        tmp_path: Path) -> None:
    session = _session(tmp_path)
    dead = RunResult(record={"error": "DutStopped", "dut_stopped": {"t_s": 3.0,
                                                                    "what": "SIGSEGV"}},
                     out_dir=tmp_path, wall_s=0.1, sim_s=3.0)
    m = session.measure("t::a", "flow.step.response_time", 0.5, run=dead)
    assert math.isnan(m.value) and m.outcome.value == "error"
    assert m.note.startswith("the DUT stopped at t = 3.0 s (SIGSEGV)")


def test_an_incomplete_session_says_what_did_not_run() -> None:
    assert Completeness(True, ["a"], {"a"}).to_dict() == {}
    assert Completeness(False, ["a", "b", "c"], {"a", "x"}).to_dict() == {
        "complete": False, "tests_planned": 3, "tests_completed": 1,
        "tests_not_run": ["b", "c"]}


def test_the_plugin_is_a_thin_layer_over_the_package() -> None:
    """hil/pytest_plugin.py holds the options, markers, fixtures and module-level hooks only:
    it defines no class (the session and its pieces live in hil.qualification), and the
    names other code imports from it are still there."""
    import hil.pytest_plugin as plugin

    tree = ast.parse(Path(plugin.__file__).read_text(encoding="utf-8"))
    assert [n.name for n in tree.body if isinstance(n, ast.ClassDef)] == []
    assert plugin.QualificationSession is QualificationSession
    assert QualificationSession.__module__ == "hil.qualification.session"
    assert plugin.SUITES == ("fast", "full", "robustness", "busload", "isobus")
    assert plugin.SCHEMA == "agrihil.qualification/1"


def test_an_operator_step_the_pool_lacks_ends_the_qualification_as_a_setup_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A scenario's ``[[operator]]`` step naming an object the implement's pool does not have
    is found once the pool is active, inside the run: the qualification stops with exit 2 and
    the step named (as ``hil run`` does), not a failed test that reads as a verdict."""
    from hil.isobus.vt.steps import OperatorScriptError
    from hil.qualification import session as session_module
    from plant_emulators.fertilizer.rig import FertilizerRig

    message = "[operator[2]] press 'Stop' for 0.2 s: no key/button labelled 'Stop' in the pool"

    def run_scenario(*args: object, **kwargs: object) -> RunResult:
        raise OperatorScriptError(message)

    monkeypatch.setattr(session_module, "run_scenario", run_scenario)
    session = _session(tmp_path)
    with pytest.raises(pytest.exit.Exception) as ended:
        session.run("t::vt", FertilizerRig, "isobus-vt-operator")
    assert ended.value.returncode == 2 and message in str(ended.value.msg)
    assert session.setup_error is not None and message in session.setup_error
