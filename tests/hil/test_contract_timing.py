"""The timing facts the rigs' contract pages state, read off short lockstep runs
(docs/guide/contract-sowing-depth.md and contract-fertilizer.md; issue 43).

Depth: sensor frames come before SYNC, the drive's TPDOs after it (so a controller computing
on SYNC sees the drive's status of one period earlier), and a controlword sent in answer to
SYNC k shows in the statusword of SYNC k+1 (synchronous RPDO). Fertilizer: the analog module
applies the command sent in answer to SYNC k at once (the motor's voltage in the next physics
step).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.rig import RunOptions, load_rig, run_scenario

ROOT = Path(__file__).resolve().parents[2]


def _run(profile_name: str, scenario: str, seconds: float, out: Path) -> Path:
    profile = load_profile(ROOT / "dut_profiles" / profile_name)
    rig = load_rig(profile.dut.rig)
    sc = rig.load_scenario(scenario)
    sc = dataclasses.replace(sc, duration_s=seconds,
                             events=tuple(e for e in sc.events if e.at_s < seconds))
    dut, _ = make_dut(profile, bus="inline", clock="lockstep", log_dir=out)
    run_scenario(rig, sc, dut, RunOptions(out_dir=out, clock="lockstep", bus="inline",
                                          record_bus=True, save_traces=True,
                                          **profile_run_options(profile)))
    return out


def _frames(out: Path) -> list[tuple[float, int, bytes, str]]:
    rows = []
    for line in (out / "bus.log").read_text().splitlines():
        stamp, _, frame, *direction = line.split()
        can_id, _, data = frame.partition("#")
        rows.append((float(stamp.strip("()")), int(can_id, 16), bytes.fromhex(data),
                     direction[0] if direction else ""))
    return rows


def test_depth_a_controller_on_sync_sees_the_drives_status_one_period_late(
        tmp_path: Path) -> None:
    frames = _frames(_run("sowing-depth-fuzzy-pid-daemon.toml", "depth-step", 0.2, tmp_path))
    syncs = [i for i, f in enumerate(frames) if f[1] == 0x080]
    assert len(syncs) >= 15
    for k, i in enumerate(syncs[1:], 1):
        t = frames[i][0]
        period = [f for f in frames[syncs[k - 1] + 1:i] if f[0] == t]
        # the period's sensor frames are sent before its SYNC, at the same instant
        assert {0x0CFF11A1, 0x0CFF10A0} <= {f[1] for f in period}, t
        after = frames[i + 1:syncs[k + 1] if k + 1 < len(syncs) else len(frames)]
        ids = [f[1] for f in after]
        # the drive's TPDO1 follows SYNC, ahead of the controller's answer (0x302)
        if 0x182 in ids:
            assert ids.index(0x182) < ids.index(0x302), t
    # a controlword answering SYNC k shows in the status of SYNC k+1, not k
    status = {f[0]: int.from_bytes(f[2][:2], "little") for f in frames if f[1] == 0x182}
    command = {f[0]: int.from_bytes(f[2][:2], "little") for f in frames if f[1] == 0x302}
    switch_on = min(t for t, cw in command.items() if cw == 0x07)     # the first "switch on"
    t_next = round(switch_on + 0.01, 6)
    assert status[round(switch_on, 6)] & 0x6F == 0x21       # ready to switch on, still
    assert status[t_next] & 0x6F == 0x23                     # switched on, one SYNC later
    # and the controller sent it on seeing "ready to switch on" a period before it computed
    assert status[round(switch_on - 0.01, 6)] & 0x6F == 0x21


def test_fertilizer_the_command_acts_at_once(tmp_path: Path) -> None:
    out = _run("fertilizer-piecewise-pid-daemon.toml", "bench-step-23", 3.3, tmp_path)
    frames = _frames(out)
    commands = [(t, int.from_bytes(d[:2], "little", signed=True)) for t, i, d, _ in frames
                if i == 0x220]
    first_t, first_mv = next((t, mv) for t, mv in commands if mv > 0)
    traces = np.load(out / "traces.npz", allow_pickle=True)
    time_s, volts = traces["time_s"], traces["command_v"]
    before = volts[np.isclose(time_s, first_t)]
    after = volts[np.isclose(time_s, first_t + 0.01)]
    assert before.size == after.size == 1
    # (the module's own gain error: 0.1 % SD)
    assert before[0] == 0.0 and abs(after[0] - first_mv / 1000.0) < 0.01 * first_mv / 1000
