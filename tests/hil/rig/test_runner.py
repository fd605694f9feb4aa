from __future__ import annotations

import json
import math
import struct
import threading
from pathlib import Path

import can
import numpy as np
import pytest

from hil.dut import InProcessDut
from hil.errors import ConfigError
from hil.record import load_traces
from hil.rig import Event, PeriodicDevice, RunOptions, Scenario, run_scenario

from .toy import SENSOR_ID, ToyController, ToyRig

STEP = Scenario(name="step", description="setpoint step", rig="toy", duration_s=5.0, seed=3,
                initial={"setpoint": 0.0}, events=(Event(at_s=1.0, set={"setpoint": 1.0}),))


def _run(tmp: Path, bus: str = "virtual", clock: str = "lockstep", seed: int | None = None,
         controller: ToyController | None = None, scenario: Scenario = STEP):
    return run_scenario(ToyRig, scenario, InProcessDut(controller or ToyController()),
                        RunOptions(out_dir=tmp, bus=bus, clock=clock, seed=seed,
                                   step_timeout_s=0.5))


def test_lockstep_run_tracks_and_records(tmp_path: Path) -> None:
    result = _run(tmp_path)
    assert result.record["verdict"] == "no-measurements" and result.record["error"] is None
    arrays, units = load_traces(tmp_path / "traces.npz")
    assert units["level"] == "m"
    assert arrays["time_s"][-1] == pytest.approx(5.0)
    assert len(arrays["time_s"]) == 501   # a row every 10 ms, both ends included
    # the P loop settles near (1 + 3) / (1 + 3) ... of the setpoint
    assert arrays["level"][-1] == pytest.approx(1.0, abs=0.05)
    assert arrays["setpoint"][0] == 0.0 and arrays["setpoint"][-1] == 1.0
    frames = list(can.LogReader(tmp_path / "bus.log"))
    syncs = [m for m in frames if m.arbitration_id == 0x080]
    assert len(syncs) == 51   # every 100 ms from 0 to 5 s
    sensor = [m.timestamp for m in frames if m.arbitration_id == SENSOR_ID]
    assert np.allclose(np.diff(sensor), 0.05)   # virtual-time stamps, exact period
    record = json.loads((tmp_path / "record.json").read_text())
    assert record["events"][0]["kind"] == "set" and record["events"][0]["t"] == 1.0
    assert record["truth"]["final_level_m"] == pytest.approx(arrays["level"][-1])


def test_same_seed_identical_traces_different_seed_differs(tmp_path: Path) -> None:
    a = load_traces(_run(tmp_path / "a", seed=1).out_dir / "traces.npz")[0]
    b = load_traces(_run(tmp_path / "b", seed=1).out_dir / "traces.npz")[0]
    c = load_traces(_run(tmp_path / "c", seed=2).out_dir / "traces.npz")[0]
    for name in a:
        np.testing.assert_array_equal(a[name], b[name])
    assert not np.array_equal(a["pump"], c["pump"])


def test_lockstep_over_the_software_bus_matches_virtual(tmp_path: Path) -> None:
    v = load_traces(_run(tmp_path / "v").out_dir / "traces.npz")[0]
    s = load_traces(_run(tmp_path / "s", bus="softbus").out_dir / "traces.npz")[0]
    for name in v:
        np.testing.assert_array_equal(v[name], s[name])


def test_silent_dut_ends_the_run_with_a_clear_error_and_keeps_traces(tmp_path: Path) -> None:
    result = _run(tmp_path, controller=ToyController(die_after_syncs=20))
    record = result.record
    assert record["verdict"] == "error"
    assert "did not answer SYNC" in record["error"] and "0x201" in record["error"]
    assert record["events"][-1]["kind"] == "run-ended"
    arrays, _ = load_traces(tmp_path / "traces.npz")
    assert arrays["time_s"][-1] == pytest.approx(2.0)   # everything up to the silence is kept
    assert json.loads((tmp_path / "record.json").read_text())["verdict"] == "error"


def test_fault_event_silences_the_sensor(tmp_path: Path) -> None:
    scenario = Scenario(name="f", description="", rig="toy", duration_s=2.0,
                        events=(Event(at_s=1.0, fault="sensor_silent"),))
    _run(tmp_path, scenario=scenario)
    stamps = [m.timestamp for m in can.LogReader(tmp_path / "bus.log")
              if m.arbitration_id == SENSOR_ID]
    assert max(stamps) < 1.0


def test_scenario_keys_are_checked_against_the_rig() -> None:
    bad = Scenario(name="x", description="", rig="toy", duration_s=1.0,
                   events=(Event(at_s=0.5, set={"setpont": 1.0}),))
    with pytest.raises(ConfigError, match=r"\[events\[0\]\.set\.setpont\] unknown input"):
        bad.check_against(ToyRig.inputs, ToyRig.faults, path="x.toml")
    with pytest.raises(ConfigError, match="unknown fault"):
        Scenario(name="x", description="", rig="toy", duration_s=1.0,
                 events=(Event(at_s=0.5, fault="melt"),)).check_against(
            ToyRig.inputs, ToyRig.faults)
    with pytest.raises(ConfigError, match="exactly one of"):
        Event(at_s=1.0)


@pytest.mark.realtime
def test_realtime_run_records_timing_health(tmp_path: Path) -> None:
    scenario = Scenario(name="rt", description="", rig="toy", duration_s=1.0,
                        initial={"setpoint": 1.0})
    result = _run(tmp_path, clock="realtime", scenario=scenario)
    timing = result.record["timing"]
    assert timing["mode"] == "realtime" and timing["ticks"] == 1000
    assert timing["lateness_p99_s"] >= 0.0 and timing["scheduler"]
    assert result.record["verdict"] in ("no-measurements", "invalid-bench")
    assert result.wall_s >= 1.0
    arrays, _ = load_traces(tmp_path / "traces.npz")
    assert arrays["level"][-1] > 0.5   # the controller really acted in real time


def test_inline_bus_gives_the_same_traces_without_threads(tmp_path: Path) -> None:
    v = load_traces(_run(tmp_path / "v").out_dir / "traces.npz")[0]
    i = load_traces(_run(tmp_path / "i", bus="inline").out_dir / "traces.npz")[0]
    for name in v:
        np.testing.assert_array_equal(v[name], i[name])
    frames = list(can.LogReader(tmp_path / "i" / "bus.log"))
    assert sum(m.arbitration_id == 0x201 and m.is_rx for m in frames) == 51


def test_inline_bus_reports_a_silent_controller(tmp_path: Path) -> None:
    result = _run(tmp_path, bus="inline", controller=ToyController(die_after_syncs=20))
    assert result.record["verdict"] == "error" and "did not answer SYNC" in result.record["error"]


def test_inline_bus_needs_lockstep(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="inline bus needs the lockstep clock"):
        _run(tmp_path, bus="inline", clock="realtime")


class _RemappingRig(ToyRig):
    """Its command frame moves when the controller reconfigures it (as a CANopen master's SDO
    write moves a drive's RPDO): 0x201 until frame 0x601 arrives, 0x202 after."""

    def __init__(self, ctx) -> None:
        super().__init__(ctx)
        self.command_id = 0x201

    def command_ids(self) -> frozenset[int]:
        return frozenset({self.command_id})

    def on_dut_frame(self, msg: can.Message, time_s: float) -> None:
        if msg.arbitration_id == 0x601:
            self.command_id = 0x202
        elif msg.arbitration_id == 0x202:
            self.pump = struct.unpack("<f", bytes(msg.data))[0]
        else:
            super().on_dut_frame(msg, time_s)


class _RemappingController(ToyController):
    """Reconfigures the rig at its 20th SYNC, then commands on 0x202."""

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        out = super().on_frame(msg)
        if msg.arbitration_id != 0x080 or self.syncs < 20:
            return out
        if self.syncs == 20:
            return [can.Message(arbitration_id=0x601, is_extended_id=False, data=b"\x01"), *out]
        return [can.Message(arbitration_id=0x202, is_extended_id=False, data=m.data)
                for m in out]


def test_lockstep_follows_a_command_frame_the_dut_moves(tmp_path: Path) -> None:
    result = run_scenario(_RemappingRig, STEP, InProcessDut(_RemappingController()),
                          RunOptions(out_dir=tmp_path, bus="virtual", step_timeout_s=0.5))
    assert result.record["error"] is None, result.record["error"]
    moved = [e for e in result.record["events"] if e["kind"] == "command-ids"]
    assert [e["detail"] for e in moved] == ["the step's command frames are now 0x202"]
    arrays, _ = load_traces(tmp_path / "traces.npz")
    assert arrays["level"][-1] == pytest.approx(1.0, abs=0.05)   # still controlled after it


class _EagerDevice(PeriodicDevice):
    """Always wants to send again at once: its next_due is just after now."""

    def __init__(self) -> None:
        super().__init__("eager", 0.1)
        self.emits = 0

    def next_due(self, time_s: float) -> float:
        return math.nextafter(time_s, math.inf)

    def frames(self, time_s: float) -> list[can.Message]:
        self.emits += 1
        return []


class _EagerRig(ToyRig):
    def __init__(self, ctx) -> None:
        super().__init__(ctx)
        self.eager = _EagerDevice()
        self.devices.append(self.eager)


def test_real_time_moves_on_when_a_device_is_always_due(tmp_path: Path) -> None:
    """A device due again at once is served at the next tick; the clock still moves (before,
    the real-time loop spun at one tick forever, growing its traces)."""
    scenario = Scenario(name="short", description="0.3 s", rig="toy", duration_s=0.3)
    done: list[object] = []
    worker = threading.Thread(target=lambda: done.append(run_scenario(
        _EagerRig, scenario, InProcessDut(ToyController()),
        RunOptions(out_dir=tmp_path, bus="virtual", clock="realtime", step_timeout_s=0.5))),
        daemon=True)
    worker.start()
    worker.join(timeout=30.0)
    assert done, "the real-time run did not end"
    arrays, _ = load_traces(tmp_path / "traces.npz")
    assert len(arrays["time_s"]) == 31 and np.all(np.diff(arrays["time_s"]) > 0)
