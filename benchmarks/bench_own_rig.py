"""Lockstep speed of a rig of your own (the fertilizer plant as an FMU, its devices from the
fertilizer DBC: docs/examples/own-rig-fertilizer-fmu) beside the built-in fertilizer rig, on
the same bench run (34 g/s per row for 50 s, enabled at 3 s: bench-constant-1700), the same
controller (the in-process reference, inline bus). Goal: the FMU rig within 2x of the
built-in's wall time.

    python -m pytest benchmarks/bench_own_rig.py -s
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from hil.cli.main import main
from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.rig import RunOptions, load_rig, run_scenario
from hil.rig.registry import RIG_FILES_ENV, register_rig_file
from hil.rig.scenario import Event, Scenario

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "docs" / "examples" / "own-rig-fertilizer-fmu"
DBC = REPO / "plant_emulators" / "fertilizer" / "db" / "fertilizer.dbc"
BUILTIN = REPO / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
WALL: dict[str, float] = {}


@pytest.fixture(scope="module")
def own_rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[type, Path]]:
    folder = tmp_path_factory.mktemp("bench-own-rig")
    assert main(["fmu", "export", "fertilizer", "--out",
                 str(folder / "build" / "fertilizer-plant.fmu"), "--fmi", "3"]) == 0
    for name in ("fertilizer-fmu.rig.toml", "piecewise-pid.toml"):
        text = (EXAMPLE / name).read_text()
        (folder / name).write_text(text.replace(
            '"../../../plant_emulators/fertilizer/db/fertilizer.dbc"', f'"{DBC}"'))
    before = os.environ.get(RIG_FILES_ENV)
    yield register_rig_file(folder / "fertilizer-fmu.rig.toml"), folder / "piecewise-pid.toml"
    if before is None:
        os.environ.pop(RIG_FILES_ENV, None)
    else:
        os.environ[RIG_FILES_ENV] = before


def _scenario(rig: type, own: bool) -> Scenario:
    if not own:
        return rig.load_scenario("bench-constant-1700")
    return Scenario(name="bench-constant-1700", description="", rig=rig.name, duration_s=53.0,
                    seed=1700, initial={"terminal_mode": 1.0, "enable": 0.0,
                                        "target_flow_gps": 34.0},
                    events=(Event(at_s=3.0, set={"enable": 1.0}),))


@pytest.mark.parametrize("which", ["builtin", "fmu"])
def test_lockstep_speed(benchmark, timed_rounds, own_rig: tuple[type, Path],
                        which: str) -> None:
    own = which == "fmu"
    rig = own_rig[0] if own else load_rig("fertilizer")
    profile = load_profile(own_rig[1] if own else BUILTIN)
    scenario = _scenario(rig, own)
    results = []

    def run() -> None:
        with tempfile.TemporaryDirectory() as out:
            dut, _ = make_dut(profile, bus="inline", clock="lockstep", log_dir=Path(out))
            results.append(run_scenario(rig, scenario, dut, RunOptions(
                out_dir=Path(out), bus="inline", **profile_run_options(profile))))

    benchmark.pedantic(run, rounds=3, iterations=1)
    assert all(r.record["error"] is None for r in results)
    truth = results[-1].record["truth"]
    metered = (truth["true_metered_total_g"] if own
               else truth["delivered_total_g"] + sum(truth["in_transit_g"]))
    assert metered == pytest.approx(4 * 1700.0, rel=0.03)      # both metered the target
    wall = float(np.median(timed_rounds()))
    WALL[which] = wall
    benchmark.extra_info.update(sim_s=scenario.duration_s, realtime_factor=53.0 / wall)
    ratio = f"; FMU rig / built-in: {WALL['fmu'] / WALL['builtin']:.2f}x" \
        if len(WALL) == 2 else ""
    print(f"\n{which} fertilizer, bench-constant-1700 lockstep, reference in-process on "
          f"inline: 53 s simulated in {wall:.2f} s (x{53.0 / wall:.0f}){ratio}")
