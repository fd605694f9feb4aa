"""The round trip: the fertilizer plant exported as an FMU, loaded as a rig of your own with
the fertilizer DBC's devices (docs/examples/own-rig-fertilizer-fmu), qualifies the fertilizer
reference with the built-in rig's step and bench-accuracy verdicts (slow: ~3 min of runs)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hil.cli.main import main
from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.metrics import accuracy_theta
from hil.rig import RunOptions, run_scenario
from hil.rig.registry import load_rig, register_rig_file
from hil.rig.scenario import Event, Scenario

REPO = Path(__file__).resolve().parents[3]
EXAMPLE = REPO / "docs" / "examples" / "own-rig-fertilizer-fmu"
DBC = REPO / "plant_emulators" / "fertilizer" / "db" / "fertilizer.dbc"
BUILTIN = REPO / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
BENCH_G = (1150, 1700, 2200)


@pytest.fixture(scope="module")
def rig_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example's rig file and profile beside the exported FMU (absolute DBC paths)."""
    folder = tmp_path_factory.mktemp("round-trip")
    fmu = folder / "build" / "fertilizer-plant.fmu"
    assert main(["fmu", "export", "fertilizer", "--out", str(fmu), "--fmi", "3"]) == 0
    for name in ("fertilizer-fmu.rig.toml", "piecewise-pid.toml"):
        text = (EXAMPLE / name).read_text()
        (folder / name).write_text(text.replace(
            '"../../../plant_emulators/fertilizer/db/fertilizer.dbc"', f'"{DBC}"'))
    return folder


def qualify(*argv: str, cwd: Path) -> dict:
    out = cwd / f"q{len(list(cwd.glob('q*')))}"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    env.pop("AGRIHIL_RIG_FILES", None)
    done = subprocess.run([sys.executable, "-m", "hil", "qualify", *argv, "--bus", "inline",
                           "--suite", "fast", "--out", str(out)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode in (0, 1), done.stderr[-3000:]
    return json.loads((out / "record.json").read_text())


def verdicts(record: dict, prefix: str) -> dict[str, bool]:
    """Pass or not of every judged measurement (information ones have no verdict)."""
    return {f"{m['name']}{sorted(m['conditions'].items())}": m["outcome"] == "pass"
            for m in record["measurements"]
            if m["name"].startswith(prefix) and m["outcome"] != "info"}


def bench_accuracy(rig: type, profile_path: Path, target_g: int, tmp: Path, *,
                   own: bool) -> float:
    """[F]'s bench constant run (50 s at target_g / 50 per row, enabled at 3 s) on ``rig``:
    eq. 15 on what a scale weighs (metered: delivered plus in the tubes)."""
    profile = load_profile(profile_path)
    if own:
        scenario = Scenario(name=f"bench-constant-{target_g}", description="", rig=rig.name,
                            duration_s=53.0, seed=target_g,
                            initial={"terminal_mode": 1.0, "enable": 0.0,
                                     "target_flow_gps": target_g / 50.0},
                            events=(Event(at_s=3.0, set={"enable": 1.0}),))
    else:
        scenario = rig.load_scenario(f"bench-constant-{target_g}")
    dut, _ = make_dut(profile, bus="inline", clock="lockstep", log_dir=tmp)
    result = run_scenario(rig, scenario, dut, RunOptions(
        out_dir=tmp, bus="inline", **profile_run_options(profile)))
    truth = result.record["truth"]
    if own:
        return accuracy_theta(target_g * 4.0, float(truth["true_metered_total_g"]))
    delivered = float(truth["delivered_total_g"]) + float(sum(truth["in_transit_g"]))
    return accuracy_theta(float(truth["target_mass_per_row_g"]) * 4, delivered)


@pytest.mark.slow
def test_the_exported_plant_gives_the_builtin_verdicts(rig_dir: Path, tmp_path: Path) -> None:
    own = qualify(str(rig_dir / "piecewise-pid.toml"), "--rig",
                  str(rig_dir / "fertilizer-fmu.rig.toml"), "-k", "test_step_response",
                  cwd=tmp_path)
    builtin = qualify(str(BUILTIN), "-k", "test_flow_step", cwd=tmp_path)
    steps_own = verdicts(own, "fertilizer_fmu.flow.step.")
    steps_builtin = verdicts(builtin, "flow.step.")
    assert steps_own and steps_builtin
    # the built-in passes every step measurement, and so does the FMU rig
    assert all(steps_builtin.values()) and all(steps_own.values())
    assert own["verdict"] == builtin["verdict"] == "pass"
    own_rig = register_rig_file(rig_dir / "fertilizer-fmu.rig.toml")
    for target_g in BENCH_G:
        a = bench_accuracy(own_rig, rig_dir / "piecewise-pid.toml", target_g,
                           tmp_path / f"own-{target_g}", own=True)
        b = bench_accuracy(load_rig("fertilizer"), BUILTIN, target_g,
                           tmp_path / f"builtin-{target_g}", own=False)
        assert (a >= 97.5) == (b >= 97.5), (target_g, a, b)     # [F]: accuracy >= 97.5 %
        assert a == pytest.approx(b, abs=1.0)
