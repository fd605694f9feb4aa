"""The depth step suite's own pieces: the hold twin, the paired signal, the steady state.

(The suite's verdicts on real DUTs are in test_suites_depth_discrimination.py.)
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import test_suites.sowing_depth.test_depth_step as suite
from hil.rig import RunResult
from plant_emulators.sowing_depth.rig import SowingDepthRig


def _run(tmp_path: Path, name: str, t: np.ndarray, **signals: np.ndarray) -> RunResult:
    out = tmp_path / name
    out.mkdir()
    units = {"time_s": "s", **{k: "mm" for k in signals}}
    np.savez(out / "traces.npz", __units__=json.dumps(units), time_s=t, **signals)
    return RunResult(record={}, out_dir=out, wall_s=1.0, sim_s=float(t[-1]))


def test_steps_are_the_scenarios() -> None:
    scenario = SowingDepthRig.load_scenario(suite.SCENARIO)
    assert scenario.initial["target_depth_mm"] == suite.HOLD_MM
    assert suite._scenario_steps(scenario) == [(s[0], s[3]) for s in suite.STEPS]
    ends = [s[1] for s in suite.STEPS]
    assert ends == [s[0] for s in suite.STEPS[1:]] + [scenario.duration_s]
    assert [s[2] for s in suite.STEPS] == [suite.HOLD_MM] + [s[3] for s in suite.STEPS[:-1]]


def test_hold_twin_keeps_everything_but_the_setpoint_changes() -> None:
    scenario = SowingDepthRig.load_scenario(suite.SCENARIO)
    hold = suite.hold_twin(scenario)
    assert hold.events == ()
    assert (hold.seed, hold.duration_s, hold.initial, hold.speed_profile, hold.rig) == (
        scenario.seed, scenario.duration_s, scenario.initial, scenario.speed_profile,
        scenario.rig)
    assert hold.name == f"{scenario.name}-hold" and repr(hold) != repr(scenario)


def test_paired_signal_removes_the_common_disturbance(tmp_path: Path) -> None:
    t = np.round(np.arange(0.0, 60.0, 0.01), 2)
    rng = np.random.default_rng(5)
    soil = np.cumsum(rng.normal(0.0, 0.05, t.size)) * 0.2 + rng.normal(0.0, 1.0, t.size)
    response = np.where(t < 15.0, 0.0, 10.0 * (1.0 - np.exp(-np.clip(t - 15.0, 0, None) / 0.3)))
    step = _run(tmp_path, "step", t, sensed_depth_mm=30.0 + response + soil)
    hold = _run(tmp_path, "hold", t, sensed_depth_mm=30.0 + soil)
    tt, y = suite.paired_sensed(step, hold)
    np.testing.assert_allclose(y, 30.0 + response, atol=1e-9)
    assert np.array_equal(tt, t)


def test_paired_signal_resamples_a_hold_run_on_other_times(tmp_path: Path) -> None:
    t = np.round(np.arange(0.0, 10.0, 0.01), 2)
    step = _run(tmp_path, "step", t, sensed_depth_mm=np.full(t.size, 31.0))
    t_hold = t + 0.004
    hold = _run(tmp_path, "hold", t_hold, sensed_depth_mm=30.0 + 0.1 * t_hold)
    _, y = suite.paired_sensed(step, hold)
    np.testing.assert_allclose(y[1:], 31.0 - 0.1 * t[1:], atol=1e-9)    # t[0] precedes it


def test_steady_state_error_is_the_mean_of_the_last_5_s_before_the_next_change() -> None:
    t = np.round(np.arange(0.0, 30.0, 0.01), 2)
    y = np.where(t < 25.0, 0.0, 19.0)
    mean, error = suite.steady_state_error(t, y, 30.0, 20.0)
    assert (mean, error) == (pytest.approx(19.0), pytest.approx(5.0))
    y[t >= 29.99] = 1000.0                     # [t_end - 5 s, t_end): 500 samples
    assert suite.steady_state_error(t, y, 30.0, 20.0)[0] == pytest.approx(
        (499 * 19.0 + 1000.0) / 500)
    y_nan = np.full(t.size, math.nan)
    assert all(math.isnan(v) for v in suite.steady_state_error(t, y_nan, 30.0, 20.0))
