"""The stored baseline: its format, the round trip, and refusing another DUT's baseline."""

from __future__ import annotations

import json
from datetime import UTC, datetime

import pytest

from hil.errors import ConfigError
from hil.gate import (
    Status,
    Verdict,
    baseline_from_record,
    check_baseline_dut,
    compare,
    load_baseline,
    parse_record,
    write_baseline,
)

from .records import DUT, good, record, write

NOW = datetime(2026, 11, 22, 12, 0, tzinfo=UTC)


def test_write_then_load_gives_the_same_baseline_and_the_record_matches_it(tmp_path) -> None:
    rec = parse_record(record(good()), path="qual/record.json")
    path = tmp_path / "baselines" / "dut.json"              # the directory is created
    write_baseline(baseline_from_record(rec, created_at=NOW), path)
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["schema"] == "agrihil.baseline/1"
    assert data["dut"] == {"name": DUT, "version": "1.0.0", "build_id": "b-0001",
                           "kind": "firmware", "rig": "fertilizer",
                           "controller": "piecewise-pid"}
    assert data["source"] == {"run_id": "3f2a9c1b7d10", "started_at": "2026-11-22T10:00:00+00:00",
                              "bus": "softbus", "clock": "lockstep", "seed": 1,
                              "suites": ["fast"]}
    assert data["created_at"] == "2026-11-22T12:00:00+00:00"
    assert list(data["measurements"]) == sorted(data["measurements"])
    assert data["measurements"]["flow.step.response_time[sensor=sliding,target_gps=23]"] == {
        "name": "flow.step.response_time", "conditions": {"target_gps": 23, "sensor": "sliding"},
        "value": 1.1, "unit": "s", "low": None, "high": 1.5}

    loaded = load_baseline(path)
    assert loaded.dut.name == DUT and loaded.source_run_id == "3f2a9c1b7d10"
    assert loaded.source["clock"] == "lockstep" and loaded.path == str(path)
    assert set(loaded.entries) == {m.key for m in rec.measurements}
    assert loaded.entries["depth.field.mean[speed_band=3-5]"].value == 30.2
    result = compare(rec, loaded)
    assert result.verdict is Verdict.PASS
    assert all(row.delta == 0.0 for row in result.rows)
    assert {row.status for row in result.rows} == {Status.PASS, Status.INFO}


def test_a_baseline_of_another_dut_is_refused_unless_forced(tmp_path) -> None:
    other = parse_record(record(good(), dut="fertilizer-piecewise-pid-daemon"), path="o.json")
    path = tmp_path / "b.json"
    write_baseline(baseline_from_record(other, created_at=NOW), path)
    rec = parse_record(record(good()), path="r.json")
    with pytest.raises(ConfigError) as info:
        check_baseline_dut(load_baseline(path), rec, force=False)
    assert str(info.value) == (f"{path}: [dut.name] baseline is of DUT "
                               f"'fertilizer-piecewise-pid-daemon', the record of '{DUT}'; "
                               f"compare them anyway with --force")
    notes = check_baseline_dut(load_baseline(path), rec, force=True)
    assert notes == [f"baseline is of DUT 'fertilizer-piecewise-pid-daemon', the record of "
                     f"'{DUT}': compared anyway (--force)"]


def test_a_hand_edited_key_that_no_longer_matches_is_refused(tmp_path) -> None:
    rec = parse_record(record(good()), path="r.json")
    data = baseline_from_record(rec, created_at=NOW).to_dict()
    entry = data["measurements"].pop("flow.bench.accuracy[target_g=1700]")
    data["measurements"]["flow.bench.accuracy[target_g=1800]"] = entry
    path = write(tmp_path / "b.json", data)
    with pytest.raises(ConfigError, match=r"\[measurements\.flow\.bench\.accuracy\[target_g=1800\]"
                                          r"\] key does not match its name and conditions"):
        load_baseline(path)


@pytest.mark.parametrize(("data", "key", "message"), [
    ({"schema": "agrihil.qualification/1"}, "[schema]", "expected 'agrihil.baseline/1'"),
    ({"schema": "agrihil.baseline/1", "dut": {"name": "x"}, "measurements": {}}, "[source]",
     "missing required key"),
    ({"schema": "agrihil.baseline/1", "dut": {"name": "x"}, "source": {"run_id": "r"},
      "measurements": {"flow.step.overshoot": {"name": "flow.step.overshoot", "conditions": {},
                                               "value": "3", "unit": "%"}}},
     "[measurements.flow.step.overshoot.value]", "expected a number"),
])
def test_a_malformed_baseline_names_file_and_key(tmp_path, data, key, message) -> None:
    path = write(tmp_path / "b.json", data)
    with pytest.raises(ConfigError) as info:
        load_baseline(path)
    assert str(info.value).startswith(f"{path}: {key} ") and message in str(info.value)


def test_a_missing_baseline_says_how_to_make_one(tmp_path) -> None:
    with pytest.raises(ConfigError, match=r"b\.json: baseline not found \(write one from a "
                                          r"passing record with 'hil gate RECORD --baseline"):
        load_baseline(tmp_path / "b.json")
