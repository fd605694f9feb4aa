"""``wiring.command_ids`` of a master that configures its slaves' RPDOs: a profile may list the
frames its master puts the commands on (the DP-200 moves the drive's RPDO1 to 0x302), and a
listed id the DUT does not send as a command, once it has configured the rig's nodes, ends the
run as a setup error naming the key."""

from __future__ import annotations

import dataclasses
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from hil.dut.inprocess import InProcessDut
from hil.rig.runner import CommandIdsError, RunOptions, run_scenario
from plant_emulators.sowing_depth.rig import SowingDepthRig
from reference_controllers.inprocess import sowing_depth_dp200, sowing_depth_fuzzy_pid

REPO = Path(__file__).resolve().parents[3]
HIL = str(Path(sys.executable).with_name("hil"))
EXAMPLE = REPO / "docs" / "examples" / "byo-depth"
PARAMS: dict[str, Any] = {"kp0": 3.0, "ki0": 0.1, "kd0": 0.0}
DP200_RIG = {"wiring": {"binding_file": str(EXAMPLE / "depthpro_dp200.binding.toml")}}


def _profile(folder: Path, command_ids: str) -> Path:
    """The DP-200's daemon profile beside its database and binding, listing ``command_ids``."""
    for name in ("depthpro_dp200.dbc", "depthpro_dp200.binding.toml"):
        shutil.copyfile(EXAMPLE / name, folder / name)
    text = (EXAMPLE / "depthpro-dp200-daemon.toml").read_text(encoding="utf-8")
    text = re.sub(r"(?m)^command_ids = .*$", f"command_ids = {command_ids}", text)
    text = text.replace('name = "depthpro-dp200-daemon"', 'name = "dp200"')
    path = folder / "dp200.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _check(path: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([HIL, "profile", "check", str(path)], capture_output=True, text=True,
                          cwd=REPO)


def test_a_profile_may_list_the_rpdo_its_master_configures(tmp_path: Path) -> None:
    done = _check(_profile(tmp_path, "[0x302]"))
    assert done.returncode == 0, done.stderr
    assert "command_ids" in done.stderr and "note" in done.stderr    # checked at run time


def test_an_id_no_rpdo_can_take_is_refused_before_any_run(tmp_path: Path) -> None:
    done = _check(_profile(tmp_path, "[0x302, 0x702]"))    # the drive's heartbeat
    assert done.returncode == 2
    assert "[wiring.command_ids]" in done.stderr and "0x702" in done.stderr
    assert "Traceback" not in done.stderr


def _run(tmp: Path, make: Any, rig: dict[str, Any], ids: set[int]) -> Any:
    scenario = dataclasses.replace(SowingDepthRig.load_scenario("depth-step"), duration_s=1.5)
    return run_scenario(SowingDepthRig, scenario, InProcessDut(make()),
                        RunOptions(out_dir=tmp, bus="inline", clock="lockstep",
                                   rig_config=rig, command_ids=frozenset(ids),
                                   command_ids_source="dp200.toml"))


def test_the_ids_the_master_configures_run(tmp_path: Path) -> None:
    result = _run(tmp_path, lambda: sowing_depth_dp200(**PARAMS), DP200_RIG, {0x302})
    assert result.record["error"] is None, result.record["error"]
    moved = [e["detail"] for e in result.record["events"] if e["kind"] == "command-ids"]
    assert moved == ["the step's command frames are now 0x302"]


def test_a_listed_id_the_dut_never_commands_on_is_a_setup_error(tmp_path: Path) -> None:
    # the DP-200 moved the drive's command RPDO to 0x302: nothing it sends at 0x202 commands
    with pytest.raises(CommandIdsError) as caught:
        _run(tmp_path, lambda: sowing_depth_dp200(**PARAMS), DP200_RIG, {0x202, 0x302})
    assert caught.value.key == "wiring.command_ids" and caught.value.path == "dp200.toml"
    assert "0x202 is not a frame the DUT sends as a command" in str(caught.value)
    assert "the rig waits after each SYNC for 0x302" in str(caught.value)


def test_the_reference_lists_the_eds_defaults_and_runs(tmp_path: Path) -> None:
    """A master that keeps the EDS's PDOs: both of its listed ids stay command frames."""
    result = _run(tmp_path, lambda: sowing_depth_fuzzy_pid(**PARAMS), {}, {0x202, 0x302})
    assert result.record["error"] is None, result.record["error"]


def test_hil_run_says_it_in_one_line_exit_2(tmp_path: Path) -> None:
    profile = _profile(tmp_path, "[0x202, 0x302]")
    done = subprocess.run([HIL, "run", "--rig", "sowing_depth", "--dut", str(profile),
                           "--scenario", "depth-step", "--bus", "inline", "--out",
                           str(tmp_path / "run")], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 2, done.stderr
    assert f"hil: error: {profile}: [wiring.command_ids] 0x202 is not a frame" in done.stderr
    assert "Traceback" not in done.stderr
