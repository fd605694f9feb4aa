"""Reading a qualification record: what the gate accepts and how it names what it refuses."""

from __future__ import annotations

import math

import pytest

from hil.errors import ConfigError
from hil.gate import load_record, measurement_key, parse_record
from hil.measurements import Measurement, Outcome

from .records import DUT, bench_accuracy, good, record, step_time, write


def test_a_documented_record_loads_with_its_identity_and_measurements(tmp_path) -> None:
    rec = load_record(write(tmp_path / "record.json", record(good())))
    assert rec.verdict == "pass" and rec.run_id == "3f2a9c1b7d10"
    assert rec.dut.name == DUT and rec.dut.version == "1.0.0" and rec.dut.build_id == "b-0001"
    assert (rec.bus, rec.clock, rec.seed, rec.suites) == ("softbus", "lockstep", 1, ("fast",))
    keys = [m.key for m in rec.measurements]
    assert keys[0] == "flow.step.response_time[sensor=sliding,target_gps=23]"
    assert keys[-1] == "rig.timing.lateness_p99"
    first = rec.measurements[0]
    assert (first.value, first.unit, first.low, first.high) == (1.10, "s", None, 1.5)
    assert first.outcome is Outcome.PASS and first.marginal is False
    assert rec.limits["flow.bench.accuracy"] == (90.0, None)


def test_identity_sorts_conditions_and_treats_23_and_23_0_alike() -> None:
    assert (measurement_key("x", {"b": 1, "a": "z"})
            == measurement_key("x", {"a": "z", "b": 1.0}) == "x[a=z,b=1]")
    assert measurement_key("x", {"on": True, "k": 0.25}) == "x[k=0.25,on=true]"


def test_an_errored_measurement_keeps_no_value(tmp_path) -> None:
    m = Measurement("flow.bench.accuracy", math.nan, "%", low=90.0)
    rec = load_record(write(tmp_path / "r.json", record([m])))
    assert rec.verdict == "fail"
    assert rec.measurements[0].value is None
    assert rec.measurements[0].checked_outcome is Outcome.ERROR


def test_a_pass_the_limits_contradict_is_checked_as_a_fail() -> None:
    data = record([step_time(1.2)])
    data["measurements"][0]["value"] = 1.9            # outside high = 1.5, outcome still "pass"
    m = parse_record(data, path="r.json").measurements[0]
    assert m.outcome is Outcome.PASS and m.checked_outcome is Outcome.FAIL


def test_unreadable_json_names_the_file(tmp_path) -> None:
    path = tmp_path / "record.json"
    path.write_text('{"schema": "agrihil.qualification/1",', encoding="utf-8")
    with pytest.raises(ConfigError, match=r"record\.json: not valid JSON .* line 1"):
        load_record(path)
    with pytest.raises(ConfigError, match=r"nope\.json: qualification record not found"):
        load_record(tmp_path / "nope.json")


@pytest.mark.parametrize(("mutate", "key", "message"), [
    (lambda d: d.update(schema="agrihil.run/1"), "[schema]", "expected 'agrihil.qualification/1'"),
    (lambda d: d.pop("schema"), "[schema]", "missing required key"),
    (lambda d: d.update(verdict="ok"), "[verdict]", "'ok' is not one of"),
    (lambda d: d["dut"].pop("name"), "[dut.name]", "missing required key"),
    (lambda d: d.update(measurements={}), "[measurements]", "expected an array"),
    (lambda d: d["measurements"][1].pop("unit"), "[measurements[1].unit]", "missing required"),
    (lambda d: d["measurements"][0].update(value="1.1"), "[measurements[0].value]",
     "expected a number, got the string '1.1'"),
    (lambda d: d["measurements"][2].update(outcome="passed"), "[measurements[2].outcome]",
     "'passed' is not one of"),
    (lambda d: d["measurements"][0].update(low=2.0), "[measurements[0].low]",
     "above the high limit"),
    (lambda d: d["measurements"][0].update(conditions=[1]), "[measurements[0].conditions]",
     "expected an object"),
])
def test_a_malformed_record_names_file_and_key(tmp_path, mutate, key, message) -> None:
    data = record(good())
    mutate(data)
    path = write(tmp_path / "bad.json", data)
    with pytest.raises(ConfigError) as info:
        load_record(path)
    text = str(info.value)
    assert text.startswith(f"{path}: {key} ") and message in text


def test_two_measurements_with_one_identity_are_refused() -> None:
    data = record([bench_accuracy(97.0), bench_accuracy(96.0)])
    with pytest.raises(ConfigError, match=r"\[measurements\[1\]\] duplicate measurement identity "
                                          r"'flow\.bench\.accuracy\[target_g=1700\]'"):
        parse_record(data, path="r.json")
