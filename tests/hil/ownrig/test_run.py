"""Runs of a rig of your own: actuator timeouts, faults, CANopen NMT, reruns byte-identical,
``hil run --rig FILE``."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import can
import numpy as np
import pytest

from hil.cli.main import main
from hil.dut.inprocess import Controller, InProcessDut
from hil.ownrig.rig import rig_class
from hil.rig import RunOptions, run_scenario
from hil.rig.scenario import Event, Scenario
from tests.hil.ownrig.test_rig_file import variant

SYNC = 0x080


class ConstantVolts(Controller):
    """Answers every SYNC with one drive command; NMT commands queued by the test."""

    name = "constant-volts"

    def __init__(self, volts: float = 5.0) -> None:
        self.volts = volts
        self.heard: list[int] = []
        self.nmt: list[can.Message] = []

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        self.heard.append(msg.arbitration_id)
        if msg.arbitration_id != SYNC:
            return []
        raw = round(self.volts / 0.001)
        out = [can.Message(arbitration_id=0x220, data=raw.to_bytes(2, "little"),
                           is_extended_id=False)]
        out += self.nmt
        self.nmt = []
        return out


@pytest.fixture
def motor(motor_rig_file: Path) -> Iterator[type]:
    sys.path.insert(0, str(motor_rig_file.parent))
    yield rig_class(motor_rig_file)
    sys.path.remove(str(motor_rig_file.parent))


def run(rig: type, scenario: Scenario, out: Path, controller: Controller | None = None,
        **kw: object) -> object:
    ctl = controller or ConstantVolts()
    return run_scenario(rig, scenario, InProcessDut(ctl), RunOptions(out_dir=out, bus="inline",
                                                                      **kw))


def scenario(rig: type, *events: Event, duration_s: float = 2.0) -> Scenario:
    return Scenario(name="t", description="", rig=rig.name, duration_s=duration_s,
                    events=tuple(events))


def test_actuator_zeroes_when_commands_stop(motor: type, tmp_path: Path) -> None:
    result = run(motor, scenario(motor, Event(at_s=1.0, fault="controller_silent")), tmp_path)
    tr, _ = result.traces()
    t, volts = tr["time_s"], tr["cmd_drive_voltage"]
    assert volts[(t > 0.5) & (t < 1.0)].min() == pytest.approx(5.0)
    # the last command at 0.9 s, the 300 ms timeout at 1.2 s: zero from there
    assert volts[(t > 1.15) & (t < 1.19)].min() == pytest.approx(5.0)
    assert np.all(volts[t >= 1.21] == 0.0)
    kinds = [e["detail"] for e in result.record["events"]
             if e["kind"] == "actuator-timeout"]
    assert kinds and "no command for 300 ms: zero" in kinds[0]


@pytest.mark.parametrize(("behaviour", "expected"), [("hold", 5.0), ("safe", 1.5)])
def test_actuator_hold_and_safe(motor_rig_file: Path, tmp_path: Path, behaviour: str,
                                expected: float) -> None:
    path = variant(motor_rig_file, 'on_timeout = "zero"', f'on_timeout = "{behaviour}"')
    if behaviour == "safe":
        path = variant(path, 'quantity = "drive_voltage" }', 'quantity = "drive_voltage", '
                       'safe = 1.5 }')
    rig = rig_class(path)
    result = run(rig, scenario(rig, Event(at_s=1.0, fault="controller_silent")), tmp_path)
    tr, _ = result.traces()
    assert tr["cmd_drive_voltage"][-1] == pytest.approx(expected)


def test_silent_and_frozen_sensor(motor: type, tmp_path: Path) -> None:
    silent = ConstantVolts()
    run(motor, scenario(motor, Event(at_s=1.0, fault="meter_silent")), tmp_path / "s", silent)
    frozen = ConstantVolts()
    result = run(motor, scenario(motor, Event(at_s=0.3, fault="meter_frozen")), tmp_path / "f",
                 frozen)
    # silent: neither its frames nor its heartbeat after 1 s (≈ 50 frames at 20 ms before)
    assert 40 <= silent.heard.count(0x181) <= 52
    # frozen: still sending every 20 ms, the same speed as at 0.3 s while the motor runs up
    assert frozen.heard.count(0x181) >= 95
    tr, _ = result.traces()
    t = tr["time_s"]
    sensed = tr["sensed_meter_speed"][t > 0.35]
    assert np.all(sensed == sensed[0]) and tr["true_y_1"][-1] > sensed[0] + 20


def test_nmt_stop_silences_a_node_and_start_resumes(motor: type, tmp_path: Path) -> None:
    class Stopper(ConstantVolts):
        steps = 0

        def on_frame(self, msg: can.Message) -> list[can.Message]:
            out = ConstantVolts.on_frame(self, msg)
            if msg.arbitration_id == SYNC:
                self.steps += 1
                if self.steps == 5:       # stop the meter (node 5) at the SYNC of 0.4 s
                    out.append(can.Message(arbitration_id=0, data=[0x02, 5],
                                           is_extended_id=False))
                if self.steps == 10:      # start it again at 0.9 s
                    out.append(can.Message(arbitration_id=0, data=[0x01, 5],
                                           is_extended_id=False))
            return out

    ctl = Stopper()
    result = run(motor, scenario(motor), tmp_path, ctl)
    assert 0x705 in ctl.heard
    tr, _ = result.traces()
    t, sensed = tr["time_s"], tr["sensed_meter_speed"]
    stopped = sensed[(t > 0.45) & (t < 0.88)]
    assert np.all(stopped == stopped[0])          # no frame while stopped
    assert sensed[-1] > stopped[0] + 5            # frames again after the start
    nmt = [e for e in result.record["events"] if e["kind"] == "nmt"]
    assert len(nmt) == 2


def test_lockstep_reruns_are_byte_identical(motor: type, tmp_path: Path) -> None:
    sc = replace(motor.load_scenario("speed-step"), duration_s=3.0, events=(
        Event(at_s=1.0, set={"speed_target": 120.0}), Event(at_s=2.0, set={"load": 0.5})))
    a = run(motor, sc, tmp_path / "a", seed=7)
    b = run(motor, sc, tmp_path / "b", seed=7)
    c = run(motor, sc, tmp_path / "c", seed=8)
    logs = [(p / "bus.log").read_bytes() for p in (tmp_path / "a", tmp_path / "b",
                                                    tmp_path / "c")]
    assert logs[0] == logs[1] and logs[0] != logs[2]       # noise from the run's seed
    ta, _ = a.traces()
    tb, _ = b.traces()
    assert all(np.array_equal(ta[k], tb[k]) for k in ta)
    tc, _ = c.traces()
    assert not np.array_equal(ta["sensed_meter_speed"], tc["sensed_meter_speed"])
    assert np.array_equal(ta["true_y_1"], tc["true_y_1"])   # the truth has no noise


def test_hil_run_with_a_rig_file(motor_rig_file: Path, tmp_path: Path,
                                 monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(motor_rig_file.parent)
    monkeypatch.syspath_prepend(str(motor_rig_file.parent))
    out = tmp_path / "run"
    code = main(["run", "--rig", str(motor_rig_file), "--dut", "pi-speed.toml",
                 "--scenario", "speed-step", "--bus", "inline", "--out", str(out)])
    assert code == 0
    assert (out / "record.json").is_file() and (out / "traces.npz").is_file()
    assert main(["run", "--rig", str(motor_rig_file), "--list-scenarios"]) == 0
