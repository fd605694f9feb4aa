"""The fertilizer rig's fast paths leave every recorded value as it was.

* ``trace_row()`` gives the values of the dict ``trace_signals()`` always built, in its order;
* flow modules skip the polls that cannot find a report: same frames at the same times, same
  traces, also when faults switch modules silent, stale or to garbage mid-window.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hil.dut import InProcessDut
from hil.record import load_traces
from hil.rig import Event, PeriodicDevice, RigContext, RunOptions, Scenario, run_scenario
from plant_emulators.fertilizer.controllers import PiFlowController
from plant_emulators.fertilizer.devices import FlowModuleDevice
from plant_emulators.fertilizer.rig import FertilizerRig


def _old_trace_signals(rig: FertilizerRig) -> dict[str, tuple[float, str]]:
    """The dict as the rig built it before trace_row() existed."""
    rig.watch(rig.time_s)
    p = rig.plant
    out: dict[str, tuple[float, str]] = {
        "target_flow_row_gps": (rig.target_flow_row_gps(), "g/s"),
        "command_v": (p.command_v, "V"),
        "motor_speed_rpm": (p.motor_speed_rpm, "rpm"),
        "shaft_speed_rpm": (p.shaft_speed_rpm, "r/min"),
        "motor_current_a": (p.motor_current_a, "A"),
        "ground_speed_mps": (rig.speed.true_speed_mps, "m/s"),
        "wheel_speed_mps": (rig.speed.hall_report().wheel_speed_mps, "m/s"),
        "analog_comm_error": (float(rig.analog.comm_error), "1"),
        "delivered_total_g": (sum(p.delivered_g), "g"),
        "target_mass_total_g": (rig.target_mass_g * rig.rows, "g"),
    }
    for row in range(rig.rows):
        out[f"flow_at_meter_{row + 1}_gps"] = (p.flow_at_meter_gps[row], "g/s")
        out[f"flow_at_sensor_{row + 1}_gps"] = (p.flow_at_sensor_gps[row], "g/s")
        out[f"sensed_flow_{row + 1}_gps"] = (rig.flow_modules[row].reported_flow_gps, "g/s")
        out[f"delivered_{row + 1}_g"] = (p.delivered_g[row], "g")
    return out


def _same(a: float, b: float) -> bool:
    return type(a) is type(b) and (a == b or (math.isnan(a) and math.isnan(b)))


def test_trace_row_is_the_old_dict_in_order() -> None:
    rig = FertilizerRig(RigContext(seed=4, rng=np.random.default_rng(4)))
    rig.set_input("terminal_mode", 0, 0.0)
    rig.set_input("rate_kg_per_hm2", 300.0, 0.0)
    rig.set_input("width_m", 2.4, 0.0)
    rig.set_input("ground_speed_mps", 1.67, 0.0)
    rig.analog.write(0x6411, 1, 3500)
    for step in range(400):
        rig.advance(10, 0.001)
        if step % 50 == 0:
            for module in rig.flow_modules:
                module.emit(rig.time_s)
        old = _old_trace_signals(rig)
        row = rig.trace_row()
        new = rig.trace_signals()
        assert list(new) == list(old)
        assert [u for _, u in new.values()] == [u for _, u in old.values()]
        assert all(_same(a, b) for a, (b, _) in zip(row, old.values(), strict=True))
        assert all(_same(a, b) for (a, _), (b, _) in zip(new.values(), old.values(),
                                                         strict=True))


FAULTS = Scenario(
    name="flow-module-faults", description="faults toggled mid-window", rig="fertilizer",
    duration_s=14.0, seed=12, initial={"terminal_mode": 1.0, "enable": 0.0,
                                       "target_flow_gps": 30.0},
    events=(Event(at_s=2.5, set={"enable": 1.0}),
            Event(at_s=4.337, fault="flow_sensor_silent", target=1),
            Event(at_s=5.05, fault="flow_sensor_stale", target=2),
            Event(at_s=6.999, clear="flow_sensor_silent", target=1),
            Event(at_s=7.0, fault="flow_sensor_garbage", target=3),
            Event(at_s=9.011, clear="flow_sensor_stale", target=2),
            Event(at_s=10.5, clear="flow_sensor_garbage", target=3),
            Event(at_s=11.2, fault="flow_sensor_silent", target=4)))


def _run(out: Path) -> Path:
    run_scenario(FertilizerRig, FAULTS, InProcessDut(PiFlowController()),
                 RunOptions(out_dir=out, bus="inline", clock="lockstep"))
    return out


def test_skipping_empty_polls_changes_no_frame_and_no_trace(tmp_path: Path,
                                                            monkeypatch) -> None:
    fast = _run(tmp_path / "fast")
    monkeypatch.setattr(FlowModuleDevice, "next_due", PeriodicDevice.next_due)
    every_poll = _run(tmp_path / "every-poll")
    assert (fast / "bus.log").read_bytes() == (every_poll / "bus.log").read_bytes()
    a, b = load_traces(fast / "traces.npz")[0], load_traces(every_poll / "traces.npz")[0]
    assert list(a) == list(b)
    for name in a:
        assert a[name].view(np.uint64).tolist() == b[name].view(np.uint64).tolist(), name
    reports = (fast / "bus.log").read_text().count(" 181#")
    assert reports > 5      # row 1's module did report (and went silent for a while)
