"""Lockstep real-time factor of a whole fertilizer field run against the reference controller.

``test_field_run_factor`` runs scenario ``field-6kmh`` (63 s) as ``hil run --dut PROFILE`` does
(the DUT built from its profile by :func:`hil.dut.factory.make_dut`, the rig overrides from
:func:`hil.dut.factory.profile_run_options`), in three ways:

``inprocess-inline``
    the daemon profile's ``launch.inprocess`` twin, called directly by the ``inline`` bus;
``firmware-softbus``
    the C firmware (host build, cached) as a process on the embedded software bus;
``daemon-softbus``
    the Python daemon as a process on the embedded software bus.

The timed call is :func:`hil.rig.run_scenario` alone: DUT start-up and stop, the embedded
software bus, the recorder's files, all of it; building the DUT (cached) is not timed.

``test_campaign_length`` runs the in-process case with the scenario's duration overridden
(15 … 252 s; ``dataclasses.replace`` on the loaded scenario, the packaged file is untouched):
a least-squares line through (length, wall) gives the fixed start-up cost and the cost per
simulated second. Issue 7's targets: ≥ 500x in process, ≥ 100x with the firmware over the
software bus (printed, never asserted)::

    python -m pytest benchmarks/bench_lockstep.py -s -p no:cacheprovider
"""

from __future__ import annotations

import dataclasses
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.dut import DutRunner
from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import DutProfile, load_profile
from hil.rig import RunOptions, RunResult, load_rig, run_scenario
from hil.rig.scenario import Scenario

ROOT = Path(__file__).resolve().parents[1]
DAEMON = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
FIRMWARE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-firmware.toml"
SCENARIO = "field-6kmh"
ROUNDS = 3
#: case -> (profile, bus, target real-time factor from issue 7, or None)
CASES: dict[str, tuple[Path, str, float | None]] = {
    "inprocess-inline": (DAEMON, "inline", 500.0),
    "firmware-softbus": (FIRMWARE, "softbus", 100.0),
    "daemon-softbus": (DAEMON, "softbus", None),
}
LENGTHS_S = (15.0, 30.0, 63.0, 126.0, 252.0)
#: campaign length -> median wall time, filled in as the lengths run (in order)
_CURVE: dict[float, float] = {}


def _missing_toolchain() -> str | None:
    """Why the firmware cannot be built here, or None when cmake and a C compiler exist."""
    if shutil.which("cmake") is None:
        return "cmake is not installed"
    if not any(shutil.which(cc) for cc in ("cc", "gcc", "clang")):
        return "no C compiler (cc, gcc or clang) is installed"
    return None


def _run_once(profile: DutProfile, scenario: Scenario, bus: str,
              results: list[RunResult]) -> None:
    """One full run of ``scenario`` against a fresh DUT of ``profile`` (timed by the caller)."""
    rig = load_rig(profile.dut.rig)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        dut: DutRunner
        dut, _ = make_dut(profile, bus=bus, clock="lockstep", log_dir=out)
        results.append(run_scenario(rig, scenario, dut,
                                    RunOptions(out_dir=out, bus=bus,
                                               **profile_run_options(profile))))


def _report(benchmark: Any, rounds: list[float], label: str, sim_s: float,
            target: float | None) -> float:
    """Median wall time of the rounds → extra_info and the README's line; returns it."""
    wall = float(np.median(rounds))
    factor = sim_s / wall
    benchmark.extra_info.update(sim_s=sim_s, wall_s=round(wall, 4),
                                realtime_factor=round(factor, 1), target_factor=target,
                                rounds=[round(t, 4) for t in rounds])
    goal = f" (target >= {target:.0f}x)" if target else ""
    print(f"\n{label}: {sim_s:.0f} s simulated in {wall:.2f} s (x{factor:.0f}){goal}; "
          f"rounds {', '.join(f'{t:.2f}' for t in rounds)} s")
    return wall


@pytest.mark.parametrize("case", list(CASES))
def test_field_run_factor(benchmark: Any, timed_rounds: Any, case: str) -> None:
    """Wall time of one 63 s field run, lockstep, per way of running the controller."""
    path, bus, target = CASES[case]
    profile = load_profile(path)
    if profile.build is not None:
        reason = _missing_toolchain()
        if reason:
            pytest.skip(f"{profile.name} needs a host build: {reason}")
        make_dut(profile, bus=bus, clock="lockstep")      # build (or find cached) untimed
    scenario = load_rig(profile.dut.rig).load_scenario(SCENARIO)
    results: list[RunResult] = []
    benchmark.pedantic(_run_once, args=(profile, scenario, bus, results),
                       rounds=ROUNDS, iterations=1, warmup_rounds=0)
    assert all(r.record["error"] is None for r in results)
    assert all(r.sim_s == pytest.approx(scenario.duration_s) for r in results)
    _report(benchmark, timed_rounds(), f"fertilizer/{SCENARIO} lockstep, {profile.name} "
            f"({case})", scenario.duration_s, target)
    ready = [r.record["dut"].get("ready_s") for r in results]
    if any(x is not None for x in ready):
        benchmark.extra_info["dut_ready_s"] = ready
        print(f"  DUT start-up (until on the bus): {', '.join(f'{x:.3f}' for x in ready)} s")


@pytest.mark.parametrize("length_s", LENGTHS_S)
def test_campaign_length(benchmark: Any, timed_rounds: Any, length_s: float) -> None:
    """Wall time of the in-process field run against the simulated length (is it linear?)."""
    profile = load_profile(DAEMON)
    scenario = dataclasses.replace(load_rig(profile.dut.rig).load_scenario(SCENARIO),
                                   duration_s=length_s)
    results: list[RunResult] = []
    benchmark.pedantic(_run_once, args=(profile, scenario, "inline", results),
                       rounds=ROUNDS, iterations=1, warmup_rounds=0)
    assert all(r.record["error"] is None for r in results)
    wall = _report(benchmark, timed_rounds(), f"campaign length {length_s:5.0f} s, in process "
                   "on inline", length_s, 500.0)
    _CURVE[length_s] = wall
    if len(_CURVE) == len(LENGTHS_S):
        lengths, walls = np.array(list(_CURVE)), np.array(list(_CURVE.values()))
        per_s, fixed = np.polyfit(lengths, walls, 1)
        worst = float(np.max(np.abs(walls - (fixed + per_s * lengths)) / walls))
        benchmark.extra_info.update(fit_fixed_s=round(float(fixed), 4),
                                    fit_per_sim_s_ms=round(float(per_s) * 1e3, 3))
        print(f"\ncampaign length fit: wall = {fixed:.3f} s + {per_s * 1e3:.2f} ms per "
              f"simulated s (asymptotic x{1 / per_s:.0f}); worst residual {worst:.1%}")

