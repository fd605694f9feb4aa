"""The report's small pure pieces."""

from __future__ import annotations

import numpy as np
import pytest

from hil.report.markup import esc, fmt_num, relative_href
from hil.report.plots_runs import _step_times, signal_role
from hil.report.plots_summary import by_name, tick_labels
from hil.report.record import MeasurementRow
from hil.report.sections_head import when


def _m(name: str = "a", outcome: str = "pass", marginal: bool = False,
       **conditions: object) -> MeasurementRow:
    return MeasurementRow(name=name, value=1.0, unit="s", low=None, high=2.0,
                          conditions=dict(conditions), outcome=outcome, marginal=marginal,
                          note="", test="t.py::test_x", run="runs/x")


@pytest.mark.parametrize(("value", "text"), [
    (None, "—"), (0.0, "0"), (1.12, "1.12"), (1852.036, "1852"), (12345.6, "12346"),
    (0.000123, "0.000123"), (1e-7, "1e-07"), (3, "3"), (123456, "123,456"), ("n/a", "n/a"),
    (float("nan"), "nan"), (True, "True")])
def test_fmt_num(value: object, text: str) -> None:
    assert fmt_num(value) == text


def test_relative_href_accepts_only_paths_inside() -> None:
    assert relative_href("runs/test_step-23/bus.log") == "runs/test_step-23/bus.log"
    assert relative_href("runs/a b/x#1") == "runs/a%20b/x%231"
    for bad in ("/etc/passwd", "../x", "runs/../../x", "http://x", "javascript:x", ""):
        assert relative_href(bad) is None, bad
    assert esc('<a href="x">&') == "&lt;a href=&quot;x&quot;&gt;&amp;"


def test_status_and_roles() -> None:
    assert _m(marginal=True).status == "marginal"
    assert _m(outcome="weird").status == "error"
    assert [signal_role(n) for n in ("target_flow_row_gps", "sensed_flow_1_gps",
                                     "flow_at_sensor_1_gps", "setpoint_mm")] == [
        "setpoint", "sensed", "truth", "setpoint"]


def test_step_times_from_the_setpoint() -> None:
    t = np.arange(0, 10, 0.5)
    sp = np.where(t < 3, 0.0, 23.0)
    sp[t >= 7] = 30.0
    assert _step_times(t, sp) == [3.0, 7.0]


def test_charts_take_repeated_names_accuracy_first() -> None:
    ms = [_m("z.time", speed=4), _m("z.time", speed=6), _m("once"),
          _m("flow.field.accuracy", speed=4), _m("flow.field.accuracy", speed=8)]
    assert [name for name, _ in by_name(ms)] == ["flow.field.accuracy", "z.time"]
    assert tick_labels(ms[:2]) == (["4", "6"], "speed")
    labels, axis = tick_labels([_m(a=1, b=2), _m(a=3)])
    assert labels == ["a=1\nb=2", "a=3"] and axis == ""


def test_when() -> None:
    assert when("2026-11-22T10:00:00+00:00") == "2026-11-22 10:00:00 UTC"
    assert when("2026-11-22T10:00:00+01:00") == "2026-11-22 10:00:00+01:00"
    assert when("yesterday") == "yesterday"


def test_why_a_test_failed() -> None:
    from hil.report.sections_head import _why

    message = "self = x\n>   return open(p)\nE   FileNotFoundError: no such file\n\nx.py:3: Err"
    assert _why(message) == "FileNotFoundError: no such file"
    assert _why("only this\n") == "only this"
    assert _why("") == "no message"
