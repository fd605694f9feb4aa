"""A rig of your own runs FMI 2.0 and FMI 3.0 plants alike (the fertilizer plant export in
both: the same C core, so the same truth), and under the real-time clock too."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.cli.main import main
from hil.dut.inprocess import InProcessDut
from hil.ownrig.rig import rig_class
from hil.rig import RunOptions, run_scenario
from hil.rig.scenario import Event, Scenario
from tests.hil.ownrig.test_run import ConstantVolts

REPO = Path(__file__).resolve().parents[3]
EXAMPLE = REPO / "docs" / "examples" / "own-rig-fertilizer-fmu"
DBC = REPO / "plant_emulators" / "fertilizer" / "db" / "fertilizer.dbc"


class Millivolts(ConstantVolts):
    """Drives the analog output module: Ch1Output in mV on 0x220, 4 bytes."""

    def on_frame(self, msg):  # type: ignore[no-untyped-def]
        self.heard.append(msg.arbitration_id)
        if msg.arbitration_id != 0x080:
            return []
        import can

        data = int(self.volts * 1000).to_bytes(2, "little", signed=True) + b"\0\0"
        return [can.Message(arbitration_id=0x220, data=data, is_extended_id=False)]


@pytest.mark.slow
def test_fmi2_and_fmi3_plants_give_the_same_truth(tmp_path: Path) -> None:
    out = tmp_path / "plant.fmu"
    assert main(["fmu", "export", "fertilizer", "--out", str(out)]) == 0
    text = (EXAMPLE / "fertilizer-fmu.rig.toml").read_text().replace(
        '"../../../plant_emulators/fertilizer/db/fertilizer.dbc"', f'"{DBC}"')
    truths = []
    for name, fmu in (("v3", out), ("v2", out.with_name("plant-fmi2.fmu"))):
        rig_file = tmp_path / f"{name}.rig.toml"
        rig_file.write_text(text.replace('"build/fertilizer-plant.fmu"', f'"{fmu}"'))
        rig = rig_class(rig_file)
        assert rig.plan().fmu.fmi_version.startswith(name[1])
        scenario = Scenario(name="t", description="", rig=rig.name, duration_s=3.0,
                            events=(Event(at_s=1.0, set={"target_flow_gps": 30.0}),))
        result = run_scenario(rig, scenario, InProcessDut(Millivolts(4.0)),
                              RunOptions(out_dir=tmp_path / name, bus="inline"))
        traces, _ = result.traces()
        truths.append(traces)
    assert truths[0]["true_delivered_total_g"][-1] > 100.0
    for key in truths[0]:
        assert np.array_equal(truths[0][key], truths[1][key]), key


@pytest.mark.slow
def test_a_node_played_from_its_eds(tmp_path: Path) -> None:
    """The analog output module from its EDS (CiA 401): its heartbeat from 0x1017, SDO and
    NMT by canopen's node, the commands into the FMU as before."""
    out = tmp_path / "plant.fmu"
    assert main(["fmu", "export", "fertilizer", "--out", str(out), "--fmi", "3"]) == 0
    eds = REPO / "plant_emulators" / "fertilizer" / "db" / "analog_output_c3402.eds"
    text = (EXAMPLE / "fertilizer-fmu.rig.toml").read_text().replace(
        '"../../../plant_emulators/fertilizer/db/fertilizer.dbc"', f'"{DBC}"').replace(
        '"build/fertilizer-plant.fmu"', f'"{out}"')
    assert 'node_id = 0x20\nheartbeat_ms = 1000' in text
    rig_file = tmp_path / "eds.rig.toml"
    rig_file.write_text(text.replace('node_id = 0x20\nheartbeat_ms = 1000',
                                     f'node_id = 0x20\neds = "{eds}"'))
    rig = rig_class(rig_file)
    ctl = Millivolts(4.0)
    scenario = Scenario(name="t", description="", rig=rig.name, duration_s=3.0)
    result = run_scenario(rig, scenario, InProcessDut(ctl), RunOptions(out_dir=tmp_path / "r",
                                                                       bus="inline"))
    assert 0x720 in ctl.heard                     # the module's heartbeat
    traces, _ = result.traces()
    assert traces["cmd_motor_command"][-1] == pytest.approx(4000.0)
    assert traces["true_shaft_speed_rpm"][-1] > 10.0
    both = tmp_path / "both.rig.toml"
    both.write_text(text.replace('node_id = 0x20\nheartbeat_ms = 1000',
                                 f'node_id = 0x20\nheartbeat_ms = 1000\neds = "{eds}"'))
    from hil.errors import ConfigError

    with pytest.raises(ConfigError, match=r"\[devices.analog_output.heartbeat_ms\]"):
        rig_class(both)


def test_realtime_run_on_the_software_bus(motor_rig_file: Path, tmp_path: Path) -> None:
    rig = rig_class(motor_rig_file)
    scenario = Scenario(name="t", description="", rig=rig.name, duration_s=1.0)
    result = run_scenario(rig, scenario, InProcessDut(ConstantVolts(5.0)), RunOptions(
        out_dir=tmp_path, bus="softbus", clock="realtime"))
    assert result.record["error"] is None
    traces, _ = result.traces()
    assert traces["true_y_1"][-1] > 50.0          # the motor ran up on the commands it heard
    assert result.record["timing"]["mode"] == "realtime"
