"""Scenario values that cannot mean what they say are refused with the file and the key
(#22.8: an event after the end of the run was silently dropped)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.errors import ConfigError
from hil.rig.registry import load_rig
from tests.fuzz.cli import assert_refused, run_cli

BASE = """name = "x"
description = "a test scenario"
rig = "fertilizer"
duration_s = {duration}
seed = {seed}
[initial]
target_flow_gps = {flow}
[[events]]
at_s = {at}
set = {{ enable = 1.0 }}
"""
GOOD = {"duration": "5.0", "seed": "3", "flow": "23.0", "at": "3.0"}


@pytest.mark.parametrize(("change", "key"), [
    ({"at": "9.0"}, "events[0].at_s"),
    ({"at": "nan"}, "events[0].at_s"),
    ({"seed": "-1"}, "seed"),
    ({"flow": "inf"}, "initial.target_flow_gps"),
    ({"duration": "1e9"}, "duration_s"),
    ({"duration": "-2.0"}, "duration_s"),
])
def test_a_scenario_value_that_cannot_be_run_is_refused(change: dict, key: str,
                                                        tmp_path: Path) -> None:
    path = tmp_path / "x.toml"
    path.write_text(BASE.format(**{**GOOD, **change}))
    with pytest.raises(ConfigError) as caught:
        load_rig("fertilizer").load_scenario(str(path))
    assert caught.value.key is not None and caught.value.key.startswith(key), caught.value
    assert str(path) in str(caught.value)
    out = tmp_path / "run"
    outcome = run_cli("run", "--rig", "fertilizer", "--dut", "builtin:pi", "--bus", "inline",
                      "--scenario", str(path), "--out", str(out))
    assert_refused(outcome, path, str(change))
    assert not out.exists()


def test_the_same_scenario_with_good_values_runs(tmp_path: Path) -> None:
    path = tmp_path / "x.toml"
    path.write_text(BASE.format(**GOOD))
    outcome = run_cli("run", "--rig", "fertilizer", "--dut", "builtin:pi", "--bus", "inline",
                      "--scenario", str(path), "--out", str(tmp_path / "run"))
    assert outcome.code == 0, outcome
    assert (tmp_path / "run" / "record.json").exists()
