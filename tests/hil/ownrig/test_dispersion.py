"""Campaigns over a rig of your own's parameters: its dispersion file is checked against the
rig file's parameters, and a sample's draws reach the FMU."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from hil.campaign.dispersion import load_dispersion
from hil.cli.campaign import check_campaign_options
from hil.dut.inprocess import InProcessDut
from hil.errors import ConfigError
from hil.rig import RunOptions, run_scenario
from hil.rig.registry import register_rig_file
from hil.rig.scenario import Scenario
from tests.hil.ownrig.test_run import ConstantVolts


def test_dispersion_names_the_rig_files_parameters(motor_rig_file: Path, tmp_path: Path) -> None:
    register_rig_file(motor_rig_file)
    dispersion = load_dispersion(motor_rig_file.with_name("dispersion.toml"), rig="motor_meter")
    assert set(dispersion.parameters) == {"parameters.drive_gain", "parameters.load_gain"}
    bad = tmp_path / "bad.toml"
    bad.write_text('[parameters.drive_gian]\ndist = "uniform"\nlow = 1.0\nhigh = 2.0\n'
                   'source = "x"\n')
    with pytest.raises(ConfigError, match=r"\[parameters.drive_gian\] unknown parameter"):
        load_dispersion(bad, rig="motor_meter")


def test_a_drawn_parameter_reaches_the_fmu(motor_rig_file: Path, tmp_path: Path) -> None:
    rig = register_rig_file(motor_rig_file)
    scenario = Scenario(name="t", description="", rig=rig.name, duration_s=2.0)
    speeds = []
    for gain in (80.0, 72.0):
        result = run_scenario(rig, scenario, InProcessDut(ConstantVolts(5.0)), RunOptions(
            out_dir=tmp_path / str(gain), bus="inline",
            rig_config={"parameters": {"drive_gain": gain}}, rig_config_source="test"))
        traces, _ = result.traces()
        speeds.append(float(traces["true_y_1"][-1]))
    # open loop at 5 V: 20 rpm/V nominal, 18 rpm/V with the gain 10 % low
    assert speeds[0] == pytest.approx(100.0, abs=0.1)
    assert speeds[1] == pytest.approx(90.0, abs=0.1)


def test_campaign_options_take_the_rig_file(motor_rig_file: Path, tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(motor_rig_file.parent)
    monkeypatch.syspath_prepend(str(motor_rig_file.parent))
    args = argparse.Namespace(profile="pi-speed.toml", rig=str(motor_rig_file), suite="fast",
                              keyword=None, bus="inline", clock="lockstep", scheduler=None,
                              dispersion=None, out=str(tmp_path / "camp"), sequential=False,
                              no_early_stop=False)
    profile, dispersion = check_campaign_options(args)
    assert profile.dut.rig == "motor_meter"
    assert "parameters.drive_gain" in dispersion.parameters     # the rig file's own default
    other = motor_rig_file.with_name("other.rig.toml")
    other.write_text(motor_rig_file.read_text().replace('name = "motor_meter"',
                                                        'name = "motor_meter_b"'))
    args.rig = str(other)
    with pytest.raises(ConfigError, match=r"\[dut.rig\] the profile is wired to the motor_meter"):
        check_campaign_options(args)
