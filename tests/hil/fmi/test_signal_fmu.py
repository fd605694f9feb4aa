"""Signal-level FMUs: the minimal FMI 3.0 controller of the docs, built by its profile's
[build], bound to rig quantities through the binding layer (units checked)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cantools
import pytest

from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.errors import ConfigError
from hil.rig.runner import RunOptions, run_scenario
from plant_emulators.fertilizer.rig import FertilizerRig

ROOT = Path(__file__).resolve().parents[3]
EXAMPLE = ROOT / "docs" / "examples" / "fmu-controller"
PROFILE = EXAMPLE / "minimal-fmu-controller.toml"
DB = cantools.database.load_file(ROOT / "plant_emulators/fertilizer/db/fertilizer.dbc")


def variant(tmp_path: Path, old: str, new: str) -> Path:
    """The example's profile with one edit, beside the example's sources (for [build])."""
    text = PROFILE.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / PROFILE.name
    path.write_text(text.replace(old, new).replace("{profile_dir}", str(EXAMPLE)),
                    encoding="utf-8")
    return path


def run(tmp: Path, profile_path: Path, seconds: float) -> Path:
    profile = load_profile(profile_path)
    dut, _ = make_dut(profile, bus="inline", clock="lockstep", log_dir=tmp)
    sc = dataclasses.replace(FertilizerRig.load_scenario("bench-step-23"), duration_s=seconds)
    result = run_scenario(FertilizerRig, sc, dut, RunOptions(out_dir=tmp, bus="inline",
                                                             clock="lockstep",
                                                             **profile_run_options(profile)))
    assert result.record.get("error") in (None, ""), result.record.get("error")
    assert result.record["dut"]["fmu_level"] == "signal"
    return tmp / "bus.log"


def commands_and_expected(log: Path, kp: float) -> list[tuple[int, int]]:
    """Each step's command (mV) and what the law says of the values the rig last sent."""
    target = flow = 0.0
    pending = False
    out = []
    for line in log.read_text().splitlines():
        _, _, frame, _ = line.split()
        can_id, data = frame.split("#")
        fid, payload = int(can_id, 16), bytes.fromhex(data)
        if fid == 0x210:
            target = DB.decode_message(fid, payload)["TargetFlow"]
        elif fid == 0x181:
            flow = DB.decode_message(fid, payload)["Flow"]
        elif fid == 0x080:
            law = min(max(85.0 * target + kp * (target - flow), 0.0), 10000.0)
            pending = True
        elif fid == 0x220 and pending:
            out.append((DB.decode_message(fid, payload)["Ch1Output"], round(law)))
            pending = False
    return out


@pytest.mark.parametrize("kp", [40.0, 0.0])
def test_the_minimal_fmu_commands_what_its_law_says_of_the_rig_values(
        tmp_path: Path, kp: float) -> None:
    profile = PROFILE if kp == 40.0 else variant(tmp_path, "kp = 40.0", f"kp = {kp}")
    pairs = commands_and_expected(run(tmp_path / "run", profile, 6.0), kp)
    assert len(pairs) == 61              # one doStep and one command per SYNC (0 to 6 s)
    assert all(got == want for got, want in pairs), pairs[:5]
    if kp:
        assert len({want for _, want in pairs}) > 3     # the values moved: the check can fail
    else:
        assert {got for got, _ in pairs} == {round(85.0 * 23.0)}   # kp reached the FMU


@pytest.mark.parametrize("old, new, key, words", [
    ('flow = "row_flow[1]"', 'flow = "wheel_speed"', "fmu.variables.flow",
     "flow is in 'g/s', wheel_speed in 'm/s'"),
    ('flow = "row_flow[1]"', "", "fmu.variables.flow", "FMU input flow is bound to no rig"),
    ('command = "motor_command"', 'command = "target_flow"', "fmu.variables.command",
     "command is an FMU output and target_flow is a quantity the rig sends"),
    ('flow = "row_flow[1]"', 'flow = "row_flow"', "fmu.variables.flow", "name the row"),
    ('flow = "row_flow[1]"', 'flow = "row_flow[1]"\nspeed = "wheel_speed"',
     "fmu.variables.speed", "the FMU has no variable 'speed'"),
    ('level = "signal"', 'level = "bus"', "", "variables bind a signal-level FMU"),
])
def test_a_wrong_binding_is_refused_naming_the_variable(
        tmp_path: Path, old: str, new: str, key: str, words: str) -> None:
    with pytest.raises(ConfigError) as info:
        profile = load_profile(variant(tmp_path, old, new))
        make_dut(profile, bus="inline", clock="lockstep")
    assert words in str(info.value)
    if key:
        assert f"[{key}]" in str(info.value)


def test_a_signal_fmu_at_bus_level_is_refused(tmp_path: Path) -> None:
    from hil.dut.build import ensure_built

    built = Path(str(ensure_built(load_profile(PROFILE))["build_dir"]))
    path = variant(tmp_path, 'level = "signal"', 'level = "bus"')
    text = path.read_text(encoding="utf-8")
    text = text.split("\n[fmu.variables]")[0] + "\n[wiring]" + text.split("[wiring]", 1)[1]
    text = text.replace("{build_dir}", str(built)).replace("kp = 40.0", "")
    text = text.split("\n[build]\n")[0] + "\n[fmu]" + text.split("\n[fmu]", 1)[1]
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match=r"\[fmu.path\] the FMU has no event mode .*; and 1 "
                                          r"more problem"):
        load_profile(path)       # the other: it declares no CAN terminal
