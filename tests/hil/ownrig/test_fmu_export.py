"""``hil fmu export fertilizer``: FMI 2.0 and 3.0 FMUs of the rig's plant C core that fmpy
validates and that replay a recorded run's truth bit for bit (noise off: the same C core and
step; noise on: the FMU's own generator, so the same physics with other flute charges)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hil.cli.main import main
from hil.dut.inprocess import InProcessDut
from hil.rig import RunOptions, run_scenario
from hil.rig.registry import load_rig
from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fmu_export.replay import TRUTH, replay
from plant_emulators.fmu_export.variables import check_against_header, run_draws, variables

NOISE_OFF = {"meter": {"flute_charge_sd_frac": 0.0}, "fertilizer": {"density_drift_sd_frac": 0.0}}


class Exports:
    """The FMUs, each built (CMake, a few seconds) when a test first asks for it."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.built: dict[int, Path] = {}

    def __getitem__(self, version: int) -> Path:
        if version not in self.built:
            out = self.folder / f"fertilizer-plant-{version}.fmu"
            assert main(["fmu", "export", "fertilizer", "--out", str(out), "--fmi",
                         str(version)]) == 0
            self.built[version] = out
        return self.built[version]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> Exports:
    """FMI 3.0 in the default run; FMI 2.0 (the same C, another skeleton) in the slow one."""
    return Exports(tmp_path_factory.mktemp("fmu-export"))


VERSIONS = [pytest.param(2, marks=pytest.mark.slow), 3]


def recorded(tmp_path: Path, overrides: dict, seed: int) -> dict[str, np.ndarray]:
    rig = load_rig("fertilizer")
    scenario = replace(rig.load_scenario("bench-step-34"), duration_s=6.0)
    pi = rig.builtin_controllers()["pi"]
    result = run_scenario(rig, scenario, InProcessDut(pi(), pi), RunOptions(
        out_dir=tmp_path, bus="inline", seed=seed, rig_config=overrides))
    assert result.record["physics_engines"]["plant"] == "native"
    traces, _ = result.traces()
    return traces


@pytest.mark.parametrize("version", VERSIONS)
def test_fmpy_validates_the_export(fmus: Exports, version: int) -> None:
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmus[version])) == []
    md = read_model_description(str(fmus[version]))
    assert md.fmiVersion == f"{version}.0" and md.coSimulation is not None
    by_name = {v.name: v for v in md.modelVariables}
    assert by_name["command_v"].causality == "input" and by_name["command_v"].unit == "V"
    assert by_name["delivered_total_g"].causality == "output"
    assert by_name["motor.supply_v"].causality == "parameter"
    assert by_name["motor.supply_v"].start == "24.0"
    assert by_name["seed"].causality == "parameter"


@pytest.mark.parametrize("version", VERSIONS)
def test_replay_reproduces_the_truth_bit_for_bit(fmus: Exports, tmp_path: Path,
                                                 version: int) -> None:
    traces = recorded(tmp_path, NOISE_OFF, seed=3)
    got = replay(fmus[version], traces, seed=3, overrides=NOISE_OFF)
    for name in TRUTH:
        assert np.array_equal(got[name], traces[name]), name
    assert traces["delivered_total_g"][-1] > 300.0        # the plant did meter


def test_replay_with_noise_is_the_same_physics(fmus: Exports, tmp_path: Path) -> None:
    traces = recorded(tmp_path, {}, seed=3)
    got = replay(fmus[3], traces, seed=3)
    assert np.array_equal(got["motor_current_a"], traces["motor_current_a"])  # drive: no noise
    assert not np.array_equal(got["flow_at_meter_1_gps"], traces["flow_at_meter_1_gps"])
    assert got["delivered_total_g"][-1] == pytest.approx(traces["delivered_total_g"][-1],
                                                         rel=0.01)


def test_header_and_variable_table_agree() -> None:
    config = load_rig_config()
    check_against_header(variables(config, run_draws(config, 0), 0))


@pytest.mark.slow
def test_export_writes_both_versions_by_default(tmp_path: Path) -> None:
    assert main(["fmu", "export", "fertilizer", "--out", str(tmp_path / "p.fmu")]) == 0
    assert (tmp_path / "p.fmu").is_file() and (tmp_path / "p-fmi2.fmu").is_file()


def test_export_refuses_what_it_cannot_build(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fmu", "export", "sowing-depth", "--out", str(tmp_path / "d.fmu")]) == 2
    assert "no FMU export for the sowing-depth rig" in capsys.readouterr().err
    assert main(["fmu", "export", "fertilizer", "--out", str(tmp_path / "p.fmu"),
                 "--rig-override", "meter.rows=3"]) == 2
    assert "rows" in capsys.readouterr().err        # refused before anything is built
