"""Limits stated per condition (issue 29): matching, the checks, the record, the report, docs.

Fast: no run of a rig (the end-to-end qualification is in
``test_per_condition_limits_qualify.py``).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.cli.main import main
from hil.condition_limits import BAND_KEYS, ConditionCase, select, when
from hil.config import from_mapping
from hil.dut.profile import Limit, load_profile
from hil.errors import ConfigError
from hil.limits import (
    CONDITIONS,
    MEASUREMENTS,
    MeasurementSpec,
    applied_limit,
    default_limit_text,
)
from hil.pytest_plugin import QualificationSession
from hil.report.record import MeasurementRow
from hil.report.sections_head import _limit_text as head_limit_text
from hil.report.sections_tables import _measurement_row

REPO = Path(__file__).resolve().parents[2]
FERTILIZER = REPO / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
DEPTH = REPO / "dut_profiles" / "sowing-depth-fuzzy-pid-daemon.toml"
TRUE_DEPTH = "depth.step.true_steady_state_error"


def _profile(tmp_path: Path, lines: str, *, reference: Path = FERTILIZER) -> Path:
    """The reference profile with ``lines`` in its ``[limits]`` table (replacing its own entries
    of those names), under the same file name."""
    names = {line.split('"')[1] for line in lines.splitlines() if line.startswith('"')}
    text = "".join(line for line in reference.read_text(encoding="utf-8").splitlines(True)
                   if not (line.startswith('"') and line.split('"')[1] in names))
    assert text.count("\n[limits]\n") == 1
    path = tmp_path / reference.name
    path.write_text(text.replace("\n[limits]\n", f"\n[limits]\n{lines}\n"), encoding="utf-8")
    return path


# --- matching ----------------------------------------------------------------------------------
def test_a_case_matches_numbers_as_numbers_and_text_as_text() -> None:
    case = ConditionCase.parse({"to_mm": 20, "high": 2.0})
    assert case.matches({"from_mm": 30.0, "to_mm": 20.0})         # the suite records floats
    assert not case.matches({"to_mm": 30.0})
    assert not case.matches({"from_mm": 20.0})                     # not carried: no match
    assert not ConditionCase.parse({"to_mm": "20", "high": 2.0}).matches({"to_mm": 20.0})
    assert not ConditionCase.parse({"row": True, "high": 1.0}).matches({"row": 1})
    both = ConditionCase.parse({"zone": ["A", "B"], "kind": "headland", "low": 97.0})
    assert both.matches({"zone": "B", "kind": "headland"})
    assert not both.matches({"zone": "B", "kind": "coverage"})
    assert both.label == "zone=A|B, kind=headland"


def test_the_first_matching_case_wins() -> None:
    cases = [when({"target_gps": 34}, high=1.0), when({"target_gps": [23, 34]}, high=2.0)]
    assert select(cases, {"target_gps": 34}, strict=False) == (0, None)
    assert select(cases, {"target_gps": 23}, strict=False) == (1, None)
    assert select(cases, {"target_gps": 44}, strict=False) == (None, None)


def test_a_case_that_cannot_be_judged_is_a_problem_wherever_it_stands() -> None:
    cases = [when({"to_mm": 20}, high=1.0), when({"to_mm": "deep"}, high=2.0)]
    index, problem = select(cases, {"to_mm": 20.0}, strict=False)
    assert index is None and problem is not None and problem.startswith("when[1] ")
    assert "'to_mm' a text where this measurement's is a number" in problem
    # a condition the measurement lacks: no match when the catalogue lists its conditions,
    # a problem when it does not
    assert select([when({"node": "x"}, high=1.0)], {}, strict=False) == (None, None)
    _, problem = select([when({"node": "x"}, high=1.0)], {"run": "r"}, strict=True)
    assert problem == ("when[0] names condition 'node', which this measurement does not have "
                       "(it has: run)")


@pytest.mark.parametrize(("table", "key", "message"), [
    ({"high": 2.0}, "when[0]", "at least one condition"),
    ({"to_mm": 20}, "when[0]", "needs low, high or both"),
    ({"to_mm": 20, "low": 3.0, "high": 2.0}, "when[0]", "low 3.0 is above high 2.0"),
    ({"to_mm": 20, "high": 2.0, "marginal": -1}, "when[0]", "marginal must be >= 0"),
    ({"to_mm": 20, "high": "2"}, "when[0].high", "expected a number"),
    ({"to_mm": {"a": 1}, "high": 2.0}, "when[0].to_mm", "a number, a string or a boolean"),
    ({"to_mm": [20, "30"], "high": 2.0}, "when[0].to_mm", "a number, a string or a boolean"),
    ({"to_mm": [], "high": 2.0}, "when[0].to_mm", "non-empty array"),
])
def test_a_bad_case_names_its_key(table: dict, key: str, message: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(message)) as info:
        ConditionCase.parse(table, key="when[0]")
    assert info.value.key == key


# --- which limit applies -----------------------------------------------------------------------
def test_profile_case_then_profile_band_then_catalogue() -> None:
    stated = Limit(high=2.5, when=({"to_mm": 20, "high": 2.0},))
    at = {"from_mm": 30.0, "to_mm": 20.0}
    assert applied_limit(TRUE_DEPTH, at, stated).high == 2.0
    assert applied_limit(TRUE_DEPTH, at, stated).source == "profile (to_mm=20)"
    other = applied_limit(TRUE_DEPTH, {**at, "to_mm": 40.0}, stated)
    assert (other.high, other.source) == (2.5, "profile")
    # a profile entry with cases only: elsewhere the catalogue's default (3 mm, hil/limits.py)
    only = Limit(when=({"to_mm": 20, "high": 2.0, "marginal": 0.1},))
    hit = applied_limit(TRUE_DEPTH, at, only)
    assert (hit.high, hit.marginal, hit.source) == (2.0, 0.1, "profile (to_mm=20)")
    miss = applied_limit(TRUE_DEPTH, {**at, "to_mm": 40.0}, only)
    assert (miss.high, miss.source) == (MEASUREMENTS[TRUE_DEPTH].high, "catalogue")
    # information only by nature: no default, so no limit
    assert applied_limit("depth.field.cv", {"speed_band_kmh": "3-5"}).source == "none"


def test_catalogue_cases_apply_when_the_profile_sets_none(monkeypatch) -> None:
    spec = MeasurementSpec("depth.step.test_only", "mm", "sowing_depth", "a test entry",
                           high=3.0, conditions=("from_mm", "to_mm"),
                           cases=(when({"to_mm": 20}, high=2.0),))
    monkeypatch.setitem(MEASUREMENTS, spec.name, spec)
    hit = applied_limit(spec.name, {"from_mm": 30.0, "to_mm": 20.0})
    assert (hit.high, hit.source) == (2.0, "catalogue (to_mm=20)")
    assert applied_limit(spec.name, {"from_mm": 30.0, "to_mm": 40.0}).source == "catalogue"
    # the profile's band replaces the catalogue's, cases included
    assert applied_limit(spec.name, {"to_mm": 20.0}, Limit(high=5.0)).high == 5.0
    assert default_limit_text(spec.name) == "to_mm=20: <= 2; otherwise <= 3"


def test_catalogue_cases_must_name_its_declared_conditions() -> None:
    assert not set(CONDITIONS) & set(BAND_KEYS)      # a condition "high" could not be named
    with pytest.raises(ValueError, match="no condition 'target_mm'"):
        MeasurementSpec("x", "mm", "sowing_depth", "", conditions=("to_mm",),
                        cases=(when({"target_mm": 20}, high=2.0),))
    with pytest.raises(ValueError, match="need its conditions"):
        MeasurementSpec("x", "mm", "sowing_depth", "", cases=(when({"to_mm": 20}, high=2.0),))
    with pytest.raises(ValueError, match="not in CONDITIONS"):
        MeasurementSpec("x", "mm", "sowing_depth", "", conditions=("depth_of_nothing",))


def test_declared_conditions_are_those_the_suites_record() -> None:
    """The conditions the catalogue lists are the ones the stored baselines' measurements carry
    (a suite that records another fails here, and a profile naming it would be refused)."""
    checked = 0
    for path in sorted((REPO / "ci" / "baselines").glob("*.json")):
        data = json.loads(path.read_text(encoding="utf-8"))
        entries = data.get("measurements")
        if not isinstance(entries, dict):
            continue                                    # a campaign baseline: other layout
        for entry in entries.values():
            spec = MEASUREMENTS.get(entry["name"])
            if spec is None or spec.conditions is None:
                continue
            assert set(entry["conditions"]) <= set(spec.conditions), (path.name, entry["name"])
            checked += 1
    assert checked > 20


# --- profiles ----------------------------------------------------------------------------------
def test_a_profile_states_limits_per_condition(tmp_path: Path) -> None:
    path = _profile(tmp_path, f'"{TRUE_DEPTH}" = {{ high = 3.0, when = [ {{ to_mm = 20, '
                              'high = 2.0 }, { to_mm = [30, 40], from_mm = 20, high = 2.5 } ] }',
                    reference=DEPTH)
    limit = load_profile(path).limits[TRUE_DEPTH]
    assert limit.high == 3.0
    assert [c.label for c in limit.cases] == ["to_mm=20", "to_mm=30|40, from_mm=20"]
    assert main(["profile", "check", str(path)]) == 0


@pytest.mark.parametrize(("line", "key", "message"), [
    # a condition the measurement never has (the steps record from_mm and to_mm)
    (f'"{TRUE_DEPTH}" = {{ high = 3.0, when = [ {{ target_mm = 20, high = 2.0 }} ] }}',
     f"limits.{TRUE_DEPTH}.when[0].target_mm", "has no condition 'target_mm'"),
    # a value of another kind
    (f'"{TRUE_DEPTH}" = {{ high = 3.0, when = [ {{ to_mm = "20", high = 2.0 }} ] }}',
     f"limits.{TRUE_DEPTH}.when[0].to_mm", "is a number, got a text"),
    # no limit in the case
    (f'"{TRUE_DEPTH}" = {{ high = 3.0, when = [ {{ to_mm = 20 }} ] }}',
     f"limits.{TRUE_DEPTH}.when[0]", "needs low, high or both"),
    # not a table
    (f'"{TRUE_DEPTH}" = {{ high = 3.0, when = [ 20 ] }}',
     f"limits.{TRUE_DEPTH}.when[0]", "expected a table"),
    # a measurement with no conditions at all
    ('"depth.fault.speed_loss.rod_travel" = { high = 3.0, when = [ { to_mm = 20, high = 1 } ] }',
     "limits.depth.fault.speed_loss.rod_travel.when[0].to_mm", "(it has: none)"),
    # the bus conformance checks judge their own limits: one per name
    ('"bus.share" = { high = 10.0, when = [ { node = "DepthControl", high = 5 } ] }',
     "limits.bus.share.when", "one limit"),
])
def test_hil_profile_check_refuses_a_bad_when(tmp_path: Path, capsys, line: str, key: str,
                                              message: str) -> None:
    path = _profile(tmp_path, line, reference=DEPTH)
    with pytest.raises(ConfigError, match=re.escape(message)) as info:
        load_profile(path)
    assert (info.value.path, info.value.key) == (str(path), key)
    assert main(["profile", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: [{key}]" in err and message in err and "Traceback" not in err


def test_the_guides_example_loads(tmp_path: Path) -> None:
    """The untagged [limits] example of docs/guide/dut-profiles.md is a valid profile table."""
    text = (REPO / "docs/guide/dut-profiles.md").read_text(encoding="utf-8")
    block = re.search(r"```\n(\[limits\]\n.*?)```", text, re.S)
    assert block is not None
    reference = DEPTH.read_text(encoding="utf-8")
    start = reference.index("\n[limits]\n")
    end = reference.index("\n[", start + 1)
    path = tmp_path / DEPTH.name
    path.write_text(reference[:start] + "\n" + block.group(1) + reference[end:],
                    encoding="utf-8")
    limits = load_profile(path).limits
    assert limits[TRUE_DEPTH].cases[0].label == "to_mm=20"
    assert limits["depth.step.overshoot"].cases[0].label == "from_mm=30, to_mm=20|40"
    assert limits["depth.field.cv"].high is None
    assert limits["depth.field.cv"].cases[0].marginal == 0.5
    assert limits["depth.field.pass_rate"].low == 90.0
    assert limits["depth.field.pass_rate"].cases[0].low == 85.0


# --- the record --------------------------------------------------------------------------------
def _session(tmp_path: Path, lines: str, reference: Path = DEPTH) -> QualificationSession:
    profile = load_profile(_profile(tmp_path, lines, reference=reference))
    return QualificationSession(profile=profile, bus="inline", clock="lockstep",
                                report_dir=tmp_path / "qual", seed=None)


def test_measure_judges_by_the_case_that_applies_and_records_it(tmp_path: Path) -> None:
    session = _session(tmp_path, f'"{TRUE_DEPTH}" = {{ high = 3.0, when = [ '
                                 '{ to_mm = 20, high = 1.0 } ] }')
    shallow = session.measure("t::a", TRUE_DEPTH, 1.5, conditions={"from_mm": 30.0,
                                                                   "to_mm": 20.0})
    deep = session.measure("t::b", TRUE_DEPTH, 1.5, conditions={"from_mm": 30.0, "to_mm": 40.0})
    assert (shallow.outcome.value, shallow.high) == ("fail", 1.0)
    assert (deep.outcome.value, deep.high) == ("pass", 3.0)
    assert [m["limit_source"] for m in session.measurements] == ["profile (to_mm=20)",
                                                                 "profile"]
    other = session.measure("t::c", "depth.step.overshoot", 4.0,
                            conditions={"from_mm": 30.0, "to_mm": 20.0, "signal": "sensed"})
    assert session.measurements[-1]["limit_source"] == "profile" and other.high == 10.0
    limits = session.record(0)["limits"][TRUE_DEPTH]
    assert limits["when"] == [{"conditions": {"to_mm": 20}, "low": None, "high": 1.0}]


def test_a_case_naming_a_condition_the_measurement_lacks_makes_it_an_error(
        tmp_path: Path) -> None:
    """Where the catalogue does not list a measurement's conditions (here the rig's own
    timing), a case is checked when the measurement is recorded."""
    session = _session(tmp_path, '"rig.timing.lateness_p99" = { high = 500.0, when = [ '
                                 '{ node = "DepthControl", high = 100.0 } ] }')
    m = session.measure("t::a", "rig.timing.lateness_p99", 80.0, conditions={"run": "r1"})
    assert m.outcome.value == "error" and math.isnan(m.value)
    assert m.note.startswith(f"limit not applied: {session.profile.path}: [limits] "
                             '"rig.timing.lateness_p99".when[0] names condition \'node\'')
    assert "measured 80 us" in m.note


# --- the report and the catalogue page ---------------------------------------------------------
def _row(source: str, low: float | None = None, high: float | None = 2.0) -> MeasurementRow:
    return MeasurementRow(name=TRUE_DEPTH, value=2.4, unit="mm", low=low, high=high,
                          conditions={"to_mm": 20.0}, outcome="fail", marginal=False, note="",
                          test="t::a", run="", limit_source=source)


def test_the_report_shows_a_per_condition_limit_as_such() -> None:
    per = _row("profile (to_mm=20)")
    assert per.per_condition == "profile: to_mm=20"
    assert "per condition (profile: to_mm=20)" in _measurement_row(per, {})
    assert head_limit_text(per) == "limit ≤ 2 (profile: to_mm=20)"
    low_only = _measurement_row(_row("catalogue (to_mm=20)", low=1.0, high=None), {})
    assert "per condition (catalogue: to_mm=20)" in low_only
    for plain in ("profile", "catalogue", ""):
        assert _row(plain).per_condition == ""
        assert "per condition" not in _measurement_row(_row(plain), {})


def test_the_catalogue_page_prints_cases_and_conditions(tmp_path: Path) -> None:
    import sys

    sys.path.insert(0, str(REPO / "docs" / "_ext"))
    try:
        from agrihil_docs import _definition
    finally:
        sys.path.remove(str(REPO / "docs" / "_ext"))
    from hil.limits import limit_text

    # the words the catalogue page, hil limits and hil profile check give a limit's cases
    limit = Limit(high=3.0, marginal=0.2, when=({"to_mm": [20, 30], "high": 2.0},))
    assert limit_text(limit.low, limit.high, limit.cases) == "to_mm=20|30: <= 2; otherwise <= 3"
    only = Limit(when=({"to_mm": 20, "low": 1.0},))
    assert limit_text(only.low, only.high, only.cases, otherwise="the default") == \
        "to_mm=20: >= 1; otherwise the default"
    assert _definition(MEASUREMENTS[TRUE_DEPTH]).endswith("(conditions: from_mm, to_mm)")
    assert _definition(MEASUREMENTS["depth.fault.speed_loss.rod_travel"]).endswith(
        "(no conditions)")


# --- any [limits] entry is used or refused, never a traceback -----------------------------------
_SCALARS = st.one_of(st.booleans(), st.integers(-10**20, 10**20),
                     st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=5),
                     st.dates(), st.none())
_VALUES = st.recursive(_SCALARS, lambda inner: st.lists(inner, max_size=3)
                       | st.dictionaries(st.text(max_size=4), inner, max_size=3), max_leaves=8)
_KEYS = st.sampled_from(["low", "high", "marginal", "to_mm", "from_mm", "zone", "node", ""])


@settings(max_examples=300, deadline=None)
@given(st.dictionaries(st.sampled_from(["low", "high", "marginal", "when"]),
                       st.one_of(_VALUES, st.lists(st.dictionaries(_KEYS, _VALUES, max_size=4),
                                                   max_size=3)), max_size=4))
def test_any_limits_entry_is_used_or_refused_naming_its_key(entry: dict) -> None:
    data = {k: v for k, v in entry.items() if v is not None}
    try:
        limit = from_mapping(Limit, data, path="p.toml", prefix=f"limits.{TRUE_DEPTH}")
    except ConfigError as exc:
        assert exc.path == "p.toml" and (exc.key or "").startswith(f"limits.{TRUE_DEPTH}")
        return
    conditions = {"from_mm": 30.0, "to_mm": 20.0}
    applied = applied_limit(TRUE_DEPTH, conditions, limit)
    assert applied.problem or applied.low is not None or applied.high is not None
