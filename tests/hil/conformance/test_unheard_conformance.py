"""Bus conformance judges what the bus log says (issue 43): the DUT's frames that a fault kept
from the rig (a cut wire) were not received, so they count for nothing; the gap they leave is
the fault's, not the DUT's, and is not judged. Once on synthetic logs (each rule, both ways),
once on a cut-wire run of the fertilizer rig."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from hil.conformance import run_conformance
from hil.conformance.framelog import FrameLog
from tests.hil.conformance.test_checks import _good_power_up, _synthetic
from tests.hil.record.test_unheard_frames import CUT, _cut_wire_run

ROOT = Path(__file__).resolve().parents[3]
CUT_S = (1.0, 2.0)


def _judge(frames, unheard=None, **kw):
    from hil.conformance.declared import build_contract
    from hil.conformance.measure import judge
    from hil.conformance.rigs import rig_bus
    from hil.dut.profile import load_profile

    profile = load_profile(ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml")
    contract = build_contract(rig_bus("fertilizer"), node_id=0x10, heartbeat_period_ms=100,
                              control_period_ms=100, command_ids=frozenset({0x220}))
    found = judge(_synthetic(frames), contract, profile, physics_period_s=0.001,
                  unheard=unheard, **kw)
    return {(m.name, m.conditions.get("message")): m for m in found.measurements}, found


def _cut(frames) -> tuple[list, FrameLog]:
    """The frames, the DUT's within the cut taken out of the log and returned apart (as the
    rig logs them: sent, not received)."""
    inside = [f for f in frames if f[4] and CUT_S[0] <= f[0] < CUT_S[1]]
    kept = [f for f in frames if f not in inside]
    return kept, _synthetic([(t, i, x, d, False) for t, i, x, d, _ in inside])


def test_the_gap_of_a_cut_wire_is_not_the_dut_s() -> None:
    heard, unheard = _cut(_good_power_up(0.0, 40))
    got, found = _judge(heard, unheard, clock="lockstep", restarts=0, duration_s=4.0)
    bad = {k: (m.value, m.note) for k, m in got.items() if m.outcome.value == "fail"}
    assert not bad, bad
    beat = next(m for (n, _), m in got.items() if n == "bus.heartbeat.max_interval")
    assert beat.value <= 100.0 + 1e-6, beat.note
    assert "not judged" in got[("bus.heartbeat.period", None)].note
    assert found.detail["unheard"]["frames"] == len(unheard)
    assert found.detail["heartbeat"]["intervals_cut"] == 1
    # the frames nobody heard are no share of the bus
    assert f"({len(heard) - sum(1 for f in heard if not f[4])} frames" in \
        got[("bus.share", None)].note


def test_without_the_unheard_frames_the_same_gap_fails_the_heartbeat() -> None:
    """The rule has teeth: the same log judged as if nothing had been lost (the DUT fell
    silent by itself) fails the heartbeat consumer's time."""
    heard, _ = _cut(_good_power_up(0.0, 40))
    got, _ = _judge(heard, None, clock="lockstep", restarts=0, duration_s=4.0)
    gaps = [m for (n, _), m in got.items() if n == "bus.heartbeat.max_interval"]
    assert gaps and all(m.value > 900 and m.outcome.value == "fail" for m in gaps)


def test_a_cut_to_the_end_ends_the_heartbeat_s_last_gap_at_the_cut() -> None:
    frames = _good_power_up(0.0, 40)
    inside = [f for f in frames if f[4] and f[0] >= 2.0]
    heard = [f for f in frames if f not in inside]
    unheard = _synthetic([(t, i, x, d, False) for t, i, x, d, _ in inside])
    got, found = _judge(heard, unheard, clock="lockstep", restarts=0, duration_s=4.0)
    assert found.detail["heartbeat"]["trailing_ms"] <= 100.0 + 1e-6
    assert all(m.outcome.value != "fail" for m in got.values())
    got, _ = _judge(heard, None, clock="lockstep", restarts=0, duration_s=4.0)
    assert any(m.outcome.value == "fail" for (n, _), m in got.items()
               if n == "bus.heartbeat.max_interval")


def test_a_sync_answered_by_a_frame_nobody_heard_has_no_latency() -> None:
    frames = [(0.0, 0x710, False, b"\x00", True)]
    for k in range(60):
        t = 0.1 * k
        frames += [(t, 0x080, False, b"", False), (t + 0.003, 0x710, False, b"\x05", True),
                   (t + 0.003, 0x220, False, b"\1\2\3\4", True)]
    heard, unheard = _cut(frames)
    got, found = _judge(heard, unheard, clock="realtime", restarts=0, duration_s=6.0)
    assert got[("bus.sync_latency.max", None)].value < 3.5
    assert found.detail["sync_latency"]["samples"] == 60 - 10
    got, _ = _judge(heard, None, clock="realtime", restarts=0, duration_s=6.0)
    assert got[("bus.sync_latency.max", None)].value > 900


def test_a_cut_wire_run_of_the_fertilizer_rig(tmp_path: Path) -> None:
    from hil.dut.profile import load_profile

    out = tmp_path / "run"
    run = _cut_wire_run("fertilizer", out)
    profile = load_profile(ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml")
    found = run_conformance(run.record, out, profile, physics_period_s=0.001)
    bad = [(m.name, m.value, m.note) for m in found.measurements if m.outcome.value == "fail"]
    assert not bad, bad
    unheard = found.detail["unheard"]
    assert unheard["frames"] == run.record["unheard"]["frames"] > 20
    assert CUT[0] <= unheard["first_s"] < unheard["last_s"] < CUT[1]
    assert found.detail["heartbeat"]["intervals_cut"] == 1
    # the same run without its unheard frames: a DUT that fell silent by itself fails
    shutil.move(out / "bus-unheard.log", tmp_path / "aside.log")
    found = run_conformance(run.record, out, profile, physics_period_s=0.001)
    assert np.any([m.outcome.value == "fail" for m in found.measurements
                   if m.name == "bus.heartbeat.max_interval"])
