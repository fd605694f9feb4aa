"""Prefix checkpoints (:mod:`hil.rig.checkpoint`): a run continued from an earlier run's
checkpoint is the run it would have been from the start, bit for bit, and only a run that
shares the prefix is continued.

The depth rig with its reference controller in process, on short copies of the fault
scenarios (events at 1 s of 2 s: the state at the first event is the same for all of them,
as at 20 s of the suite's 40 s runs).
"""

from __future__ import annotations

import dataclasses
import os
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.rig import RunOptions, RunResult, Scenario, checkpoint, run_scenario
from hil.rig.base import RigContext
from hil.rig.scenario import Event
from plant_emulators.sowing_depth.rig import SowingDepthRig

ROOT = Path(__file__).resolve().parents[3]
#: a checkpoint holds only in a process with no other thread (tests/hil/rig/conftest.py)
RUN_EACH_TEST_IN_A_FORK = True
PROFILE = load_profile(ROOT / "dut_profiles/sowing-depth-fuzzy-pid-daemon.toml")
AT_S = 1.0


@pytest.fixture(autouse=True)
def _no_holders():
    checkpoint.release_all()
    yield
    checkpoint.release_all()


def _short(name: str, **change: Any) -> Scenario:
    """A packaged fault scenario cut to 2 s, its events moved by 19 s (20 s -> 1 s)."""
    scenario = SowingDepthRig.load_scenario(name)
    events = tuple(dataclasses.replace(e, at_s=e.at_s - 20.0 + AT_S) for e in scenario.events
                   if e.at_s - 20.0 + AT_S < 2.0)
    return dataclasses.replace(scenario, **{"duration_s": 2.0, "events": events, **change})


def _run(scenario: Scenario, out: Path, *, held: bool = True, **options: Any) -> RunResult:
    """The scenario on the depth rig against the reference in process, measurements only."""
    if not held:
        checkpoint.release_all()
    dut, _ = make_dut(PROFILE, bus="inline", clock="lockstep")
    result = run_scenario(SowingDepthRig, scenario, dut, _options(out, **options))
    if not held:
        checkpoint.release_all()
    return result


def _options(out: Path, **change: Any) -> RunOptions:
    return RunOptions(out_dir=out, bus="inline", clock="lockstep", record_bus=False,
                      save_traces=False, seed=8700001,
                      extra_meta={"dut_identity": PROFILE.identity(), "test": out.name},
                      **{**profile_run_options(PROFILE, rig_from=PROFILE), **change})


def _key(scenario: Scenario, options: RunOptions) -> tuple[Any, ...] | None:
    dut, _ = make_dut(PROFILE, bus="inline", clock="lockstep")
    return checkpoint.prefix_key(SowingDepthRig, scenario, dut, options)


def _holder(scenario: Scenario, out: Path) -> object:
    """The holder a run of ``scenario`` would continue from, or None."""
    return checkpoint.holder_for(_key(scenario, _options(out)), scenario,
                                 SowingDepthRig.physics_period_s)


def _same(a: RunResult, b: RunResult) -> None:
    """Every trace and truth array and the record's facts, bit for bit."""
    ta, tb = a.traces()[0], b.traces()[0]
    assert ta.keys() == tb.keys()
    for name in ta:
        np.testing.assert_array_equal(ta[name], tb[name], err_msg=name)
    truth_a, truth_b = a.truth_arrays(), b.truth_arrays()
    assert truth_a.keys() == truth_b.keys() and truth_a
    for name in truth_a:
        np.testing.assert_array_equal(truth_a[name], truth_b[name], err_msg=name)
    for key in ("verdict", "error", "seeds", "events", "frames", "sim_s", "scenario",
                "dut"):
        assert a.record.get(key) == b.record.get(key), key
    truth = {k: v for k, v in a.record["truth"].items() if k != "gnss_epochs"}
    assert truth == {k: v for k, v in b.record["truth"].items() if k != "gnss_epochs"}


def test_runs_continued_from_a_checkpoint_are_the_runs_from_the_start(tmp_path: Path) -> None:
    first = _run(_short("fault-inclinometer-stuck"), tmp_path / "stuck")
    assert len(checkpoint._holders) == 1      # held at its first event
    later = {name: _short(name) for name in ("fault-inclinometer-noisy", "fault-dut-restart",
                                             "fault-saturation-recovery")}
    later["twin"] = dataclasses.replace(_short("fault-inclinometer-stuck"), name="fault-twin",
                                        events=())
    resumed = {}
    for name, scenario in later.items():
        assert _holder(scenario, tmp_path) is not None, name
        resumed[name] = _run(scenario, tmp_path / f"{name}-resumed")
    for name, scenario in later.items():
        _same(resumed[name], _run(scenario, tmp_path / f"{name}-fresh", held=False))
        assert resumed[name].record["continued_from_checkpoint_s"] == AT_S   # not from 0
        assert resumed[name].record["scenario"] == scenario.name
        assert resumed[name].record["test"] == f"{name}-resumed"
        assert resumed[name].record["run_id"] != first.record["run_id"]
        assert (tmp_path / f"{name}-resumed" / "record.json").is_file()
    _same(first, _run(_short("fault-inclinometer-stuck"), tmp_path / "stuck-fresh", held=False))


def test_the_comparison_tells_a_different_run(tmp_path: Path) -> None:
    """The bit-for-bit check above fails a run that differs after the event (it is not a
    check that cannot fail)."""
    stuck = _run(_short("fault-inclinometer-stuck"), tmp_path / "a", held=False)
    noisy = _run(_short("fault-inclinometer-noisy"), tmp_path / "b", held=False)
    with pytest.raises(AssertionError):
        _same(stuck, noisy)


@pytest.mark.parametrize("change", [
    {"seed": 8}, {"initial": {"target_depth_mm": 30.0, "ground_speed_mps": 1.2}},
    {"events": (Event(at_s=0.5, fault="inclinometer_noisy"),)},
])
def test_a_run_that_does_not_share_the_prefix_starts_from_the_start(
        tmp_path: Path, change: dict[str, Any]) -> None:
    _run(_short("fault-inclinometer-stuck"), tmp_path / "first")
    assert _holder(_short("fault-inclinometer-noisy"), tmp_path) is not None
    assert _holder(_short("fault-inclinometer-noisy", **change), tmp_path) is None


@pytest.mark.parametrize("options", [
    {"record_bus": True}, {"save_traces": True}, {"extra_meta": {}},
    {"rig_config": {"gnss": {"output_rate_hz": 5.0}}},
])
def test_what_a_run_writes_its_dut_and_its_rig_config_are_in_the_key(
        tmp_path: Path, options: dict[str, Any]) -> None:
    first = _short("fault-inclinometer-stuck")
    key = _key(first, _options(tmp_path))
    assert key is not None
    assert _key(first, dataclasses.replace(_options(tmp_path), **options)) != key


def test_an_error_in_the_continued_run_is_raised_here(tmp_path: Path) -> None:
    _run(_short("fault-inclinometer-stuck"), tmp_path / "first")
    bad = dataclasses.replace(_short("fault-inclinometer-stuck"), name="bad",
                              events=(Event(at_s=1.5, fault="no_such_fault"),))
    assert _holder(bad, tmp_path) is not None
    with pytest.raises(Exception, match="no_such_fault"):
        _run(bad, tmp_path / "bad")
    assert len(checkpoint._holders) == 1     # the holder serves the next run all the same
    _run(_short("fault-inclinometer-noisy"), tmp_path / "next")


def test_a_holder_that_is_gone_is_a_run_from_the_start(tmp_path: Path) -> None:
    _run(_short("fault-inclinometer-stuck"), tmp_path / "first")
    (holder,) = checkpoint._holders.values()
    os.kill(holder.pid, signal.SIGKILL)
    noisy = _short("fault-inclinometer-noisy")
    run = _run(noisy, tmp_path / "noisy")
    assert "continued_from_checkpoint_s" not in run.record
    assert len(checkpoint._holders) == 1 and holder not in checkpoint._holders.values()
    _same(run, _run(noisy, tmp_path / "noisy-fresh", held=False))


def test_an_interrupted_wait_lets_the_holder_go(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Its answer may still come: a later run must not read it as its own."""
    _run(_short("fault-inclinometer-stuck"), tmp_path / "first")

    def interrupted(sock: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(checkpoint, "_receive", interrupted)
    with pytest.raises(KeyboardInterrupt):
        _run(_short("fault-inclinometer-noisy"), tmp_path / "noisy")
    assert not checkpoint._holders


class _ReadsItsScenario(SowingDepthRig):
    """The depth rig, but one that looks at its scenario when it is built (as a rig that
    prepares its faults from the events would)."""

    def __init__(self, ctx: RigContext) -> None:
        self.events_at_build = len(ctx.scenario.events) if ctx.scenario else 0
        super().__init__(ctx)


@pytest.mark.parametrize("rig_cls, held", [(SowingDepthRig, True), (_ReadsItsScenario, False)])
def test_a_rig_that_reads_its_scenario_is_never_held(tmp_path: Path, rig_cls: type,
                                                     held: bool) -> None:
    """Its state at the first event may depend on the events after it: no later run may
    continue from it. The same rig that does not read its scenario is held (the control)."""
    scenario = _short("fault-inclinometer-stuck")
    dut, _ = make_dut(PROFILE, bus="inline", clock="lockstep")
    run = run_scenario(rig_cls, scenario, dut, _options(tmp_path / "first"))
    assert run.record["error"] is None
    later = _short("fault-inclinometer-noisy")
    key = checkpoint.prefix_key(rig_cls, later, dut, _options(tmp_path))
    assert key is not None                  # a run the checkpoints would take
    holder = checkpoint.holder_for(key, later, rig_cls.physics_period_s)
    assert (holder is not None) is held
    assert len(checkpoint._holders) == int(held)


def test_the_rig_context_tells_whether_its_scenario_was_read() -> None:
    scenario = _short("fault-inclinometer-stuck")
    ctx = RigContext(seed=1, rng=np.random.default_rng(1), scenario=scenario)
    assert not ctx.scenario_read
    assert ctx.scenario is scenario and ctx.scenario_read
    bare = RigContext(seed=1, rng=np.random.default_rng(1))
    assert bare.scenario is None and bare.scenario_read
    assert not RigContext(seed=1, rng=np.random.default_rng(1), scenario=None).scenario_read
