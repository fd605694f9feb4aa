"""The fertilizer rig end to end: physics + devices + DBC/EDS + scenarios under both clocks."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import can
import canopen
import numpy as np
import pytest

from hil.dut import InProcessDut
from hil.record import load_traces
from hil.rig import Event, RunOptions, Scenario, run_scenario
from hil.softbus import SoftwareBus
from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fertilizer.controllers import OpenLoopController, PiFlowController
from plant_emulators.fertilizer.frames import FertilizerDatabase
from plant_emulators.fertilizer.rig import FertilizerRig


def _run(tmp: Path, scenario: str | Scenario, *, controller=None, seed=None, bus="virtual",
         clock="lockstep"):
    sc = FertilizerRig.load_scenario(scenario) if isinstance(scenario, str) else scenario
    return run_scenario(FertilizerRig, sc, InProcessDut(controller or PiFlowController()),
                        RunOptions(out_dir=tmp, bus=bus, clock=clock, seed=seed))


def _short(duration: float = 8.0, target: float = 34.0, events: tuple = ()) -> Scenario:
    return Scenario(name="short", description="", rig="fertilizer", duration_s=duration,
                    initial={"terminal_mode": 1.0, "enable": 0.0, "target_flow_gps": target},
                    events=(Event(at_s=3.0, set={"enable": 1.0}), *events))


def test_every_packaged_scenario_loads_and_is_checked() -> None:
    names = [name for name, _ in FertilizerRig.scenario_names()]
    assert {"bench-step-23", "bench-constant-1700", "field-8kmh", "fault-sensor-silent",
            "fault-controller-silent", "fault-motor-stall"} <= set(names)
    for name in names:
        assert FertilizerRig.load_scenario(name).rig == "fertilizer"


def test_same_seed_identical_traces_and_frames(tmp_path: Path) -> None:
    a = _run(tmp_path / "a", _short(), seed=4)
    b = _run(tmp_path / "b", _short(), seed=4)
    c = _run(tmp_path / "c", _short(), seed=5)
    ta, tb, tc = (load_traces(r.out_dir / "traces.npz")[0] for r in (a, b, c))
    for name in ta:
        np.testing.assert_array_equal(ta[name], tb[name], err_msg=name)
    assert not np.array_equal(ta["flow_at_sensor_1_gps"], tc["flow_at_sensor_1_gps"])

    def rig_frames(run) -> list[tuple]:   # what the rig sent: the plant's side of the bus
        return [(m.timestamp, m.arbitration_id, bytes(m.data))
                for m in can.LogReader(run.out_dir / "bus.log") if not m.is_rx]

    assert rig_frames(a) == rig_frames(b)


def test_the_rig_speaks_only_frames_its_databases_define(tmp_path: Path) -> None:
    run = _run(tmp_path, _short())
    db = FertilizerDatabase.from_config(load_rig_config())
    canopen_ids = {0x080} | {0x700 + n for n in (1, 2, 3, 4, 5, 0x20)}
    seen = set()
    for msg in can.LogReader(run.out_dir / "bus.log"):
        if msg.is_rx:
            continue
        seen.add(msg.arbitration_id)
        if msg.arbitration_id in canopen_ids:
            continue
        name, signals = db.decode(msg)     # raises on an unknown frame
        assert signals, name
    assert {0x181, 0x182, 0x183, 0x184, 0x185, 0x210, 0x0CFE48F0, 0x0CFE49F0, 0x080} <= seen


def test_closed_loop_beats_open_loop_on_delivered_mass(tmp_path: Path) -> None:
    """The rig's truth tells a controller that corrects from the sensors from one that
    does not: the fertilizer delivers ~3-4 % less than the meter's nominal map ([F])."""
    scenario = _short(duration=23.0, target=34.0)
    pi = _run(tmp_path / "pi", scenario).record["truth"]
    ol = _run(tmp_path / "ol", scenario, controller=OpenLoopController()).record["truth"]
    target = pi["target_mass_per_row_g"] * 4
    pi_err = abs(pi["delivered_total_g"] + sum(pi["in_transit_g"]) - target) / target
    ol_err = abs(ol["delivered_total_g"] + sum(ol["in_transit_g"]) - target) / target
    assert ol_err > 0.02
    assert pi_err < ol_err


def test_cut_wire_makes_the_analog_module_fall_back_to_zero(tmp_path: Path) -> None:
    run = _run(tmp_path, _short(duration=10.0,
                                events=(Event(at_s=6.0, fault="controller_silent"),)))
    tr = load_traces(run.out_dir / "traces.npz")[0]
    t = tr["time_s"]
    assert tr["command_v"][(t > 4) & (t < 6)].min() > 2.0
    assert np.all(tr["command_v"][t > 6.35] == 0.0)           # 300 ms consumer time
    assert np.all(tr["analog_comm_error"][t > 6.35] == 1.0)
    kinds = [e["detail"] for e in run.record["events"] if e["kind"] == "dut-heartbeat"]
    assert kinds == ["controller heartbeat lost"]


def test_stall_stops_the_shaft_and_the_flow(tmp_path: Path) -> None:
    run = _run(tmp_path, _short(duration=12.0, events=(Event(at_s=6.0, fault="motor_stall"),
                                                       Event(at_s=9.0, clear="motor_stall"))))
    tr = load_traces(run.out_dir / "traces.npz")[0]
    t = tr["time_s"]
    assert np.all(tr["shaft_speed_rpm"][(t > 6.05) & (t < 9.0)] == 0.0)
    assert tr["motor_current_a"][(t > 6.5) & (t < 9.0)].max() > 3.0
    assert tr["flow_at_meter_1_gps"][(t > 6.1) & (t < 9.0)].max() == 0.0
    assert tr["shaft_speed_rpm"][t > 10.0].min() > 10.0        # recovers


def test_silent_sensor_sends_nothing_after_the_fault(tmp_path: Path) -> None:
    run = _run(tmp_path, _short(duration=10.0, events=(
        Event(at_s=5.5, fault="flow_sensor_silent", target=2),)))
    row2 = [m.timestamp for m in can.LogReader(run.out_dir / "bus.log")
            if m.arbitration_id == 0x182 and not m.is_rx]
    row1 = [m.timestamp for m in can.LogReader(run.out_dir / "bus.log")
            if m.arbitration_id == 0x181 and not m.is_rx]
    assert max(row2) < 5.5 and max(row1) > 9.0


def test_a_canopen_master_reads_and_writes_the_analog_module(tmp_path: Path) -> None:
    eds = str(load_rig_config().wiring.analog_output_eds_file)
    with SoftwareBus(port=0) as softbus:
        result: dict = {}
        runner = threading.Thread(target=lambda: result.update(run=_run(
            tmp_path, _short(duration=4.0), bus=softbus.spec(), clock="realtime",
            controller=_Quiet())))
        network = canopen.Network()
        network.connect(interface="socketcand", host=softbus.host, port=softbus.port,
                        channel="can0", tcp_tune=True)
        try:
            runner.start()
            node = network.add_node(0x20, eds)
            time.sleep(0.5)
            assert node.sdo[0x1000].raw == 0x00080191
            node.sdo[0x6411][1].raw = 2500              # 2.5 V on the motor command
            assert node.sdo[0x6411][1].raw == 2500
            time.sleep(1.0)
        finally:
            runner.join(15)
            network.disconnect()
    tr = load_traces(tmp_path / "traces.npz")[0]
    assert tr["command_v"][-1] == pytest.approx(2.5, abs=0.02)
    assert tr["shaft_speed_rpm"][-1] == pytest.approx(15.0, rel=0.05)   # 6 r/min per volt
    timing = result["run"].record["timing"]
    assert timing["mode"] == "realtime" and timing["ticks"] == 4000


class _Quiet(PiFlowController):
    """Sends nothing, not even its boot-up: the SDO master is the only one driving the module."""

    def on_start(self) -> list[can.Message]:
        return []

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        return []


def test_hil_run_command(tmp_path: Path) -> None:
    listing = subprocess.run([sys.executable, "-m", "hil", "run", "--rig", "fertilizer",
                              "--list-scenarios"], capture_output=True, text=True, check=True)
    first_words = [line.split()[0] for line in listing.stdout.splitlines()]
    assert "bench-step-34" in first_words and "field-4kmh" in first_words
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "hil", "run", "--rig", "fertilizer", "--dut",
                           "builtin:pi", "--scenario", "fault-sensor-silent", "--out", str(out),
                           "--plot", "--csv"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert {"record.json", "bus.log", "bus.asc", "traces.npz", "traces.csv", "plot.png"} <= {
        p.name for p in out.iterdir()}
    record = json.loads((out / "record.json").read_text())
    assert record["rig"] == "fertilizer" and record["scenario"] == "fault-sensor-silent"
    bad = subprocess.run([sys.executable, "-m", "hil", "run", "--rig", "fertilizer", "--dut",
                          "builtin:pi", "--scenario", "no-such"], capture_output=True, text=True)
    assert bad.returncode == 2
    assert "available: bench-busload-1700, bench-constant-1150" in bad.stderr
