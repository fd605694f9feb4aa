"""Bus conformance discriminates: the reference controllers (daemon and firmware, both rigs)
pass every conformance measurement, in lockstep and in real time, and each must-fail bus
profile (``dut_profiles/must_fail/bus/*-bus-*-daemon.toml``) fails exactly the measurement its
defect breaks while its control law (the reference's) passes the control suites.

The default run uses short scenarios (a few simulated seconds each, with a DUT restart for
the boot-up rule); the check through ``hil qualify`` that the must-fail profiles pass the
control suites runs the step suites in a subprocess per profile and is marked ``slow``.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import cantools
import pytest

from hil.conformance import run_conformance
from hil.conformance.framelog import read_bus_log
from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import DutProfile, load_profile
from hil.measurements import Measurement, Outcome
from hil.rig import RunOptions, load_rig, run_scenario
from hil.rig.scenario import Event, Scenario

ROOT = Path(__file__).resolve().parents[3]
PROFILES = ROOT / "dut_profiles"
#: beside the suites' must-fail profiles, whose tests check that every profile of must_fail/
#: is theirs
BUS = PROFILES / "must_fail" / "bus"
REFERENCES = ["fertilizer-piecewise-pid-daemon", "fertilizer-piecewise-pid-firmware",
              "sowing-depth-fuzzy-pid-daemon", "sowing-depth-fuzzy-pid-firmware"]
#: must-fail profile → the conformance measurements its defect must fail (and no other)
EXPECTED: dict[str, set[str]] = {}
#: besides: the frames of a step sent before the boot-up of a restarted DUT fall in the power-up
#: before it (boot-ups delimit power-ups), where they make one short status interval
SIDE_EFFECTS = {"talks-before-bootup": {"bus.cycle_time.outside_band"},
                # a heartbeat five times too slow also outlasts a consumer's time when the
                # consumer (or the rig's monitor, 2 periods) is stricter than 5 periods
                "slow-heartbeat": {"bus.heartbeat.max_interval"}}
for _rig in ("fertilizer", "sowing-depth"):
    EXPECTED.update({
        f"{_rig}-bus-command-twice-daemon": {"bus.cycle_time.median",
                                             "bus.cycle_time.outside_band"},
        f"{_rig}-bus-wrong-dlc-daemon": {"bus.dlc_errors"},
        f"{_rig}-bus-slow-heartbeat-daemon": {"bus.heartbeat.period"},
        f"{_rig}-bus-heartbeat-stops-daemon": {"bus.heartbeat.max_interval"},
        f"{_rig}-bus-debug-frame-daemon": {"bus.undeclared_frames"},
        f"{_rig}-bus-talks-before-bootup-daemon": {"bus.bootup.frames_before"},
        f"{_rig}-bus-double-bootup-daemon": {"bus.bootup.unexpected"},
    })
#: defects whose bus fault a rig node acts on, so the control suites see it too (the defect
#: must still fail its conformance measurement)
CONTROL_CONSEQUENCES = {
    "fertilizer-bus-heartbeat-stops-daemon":
        "the analog output module consumes the controller's heartbeat (0x1016, 300 ms) and puts "
        "its output to the error value (0x6444: motor stopped) when it stops, as on a planter",
}
#: rig → (scenario, seconds it is cut to, restart at)
SHORT = {"fertilizer": ("fault-dut-restart", 8.0, 4.0),
         "sowing_depth": ("fault-dut-restart", 4.0, 2.0)}
#: rig → (scenario, seconds) for the real-time runs
REALTIME = {"fertilizer": ("bench-step-23", 5.0), "sowing_depth": ("depth-step", 3.0)}


def _short(scenario: Scenario, duration_s: float, restart_at: float | None) -> Scenario:
    events = [e for e in scenario.events if e.dut != "restart" and e.at_s < duration_s]
    if restart_at is not None:
        events.append(Event(at_s=restart_at, dut="restart"))
    return dataclasses.replace(scenario, duration_s=duration_s, events=tuple(events))


def _run(profile: DutProfile, scenario: Scenario, out: Path, *, bus: str,
         clock: str) -> tuple[dict, list[Measurement]]:
    rig = load_rig(profile.dut.rig)
    dut, _ = make_dut(profile, bus=bus, clock=clock, log_dir=out)
    result = run_scenario(rig, scenario, dut, RunOptions(
        out_dir=out, clock=clock, bus=bus, step_timeout_s=10.0,
        **profile_run_options(profile)))
    found = run_conformance(result.record, out, profile,
                            physics_period_s=rig.physics_period_s)
    return result.record, found.measurements


def _lockstep_run(name: str, directory: Path, out: Path, bus: str) -> tuple[dict,
                                                                          list[Measurement]]:
    profile = load_profile(directory / f"{name}.toml")
    rig = load_rig(profile.dut.rig)
    scenario_name, duration, restart = SHORT[rig.name]
    scenario = _short(rig.load_scenario(scenario_name), duration, restart)
    return _run(profile, scenario, out, bus=bus, clock="lockstep")


def _failing(measurements: list[Measurement]) -> set[str]:
    return {m.name for m in measurements if m.outcome in (Outcome.FAIL, Outcome.ERROR)}


def test_every_bus_profile_is_covered() -> None:
    found = sorted(p.stem for p in BUS.glob("*-bus-*-daemon.toml"))
    assert found == sorted(EXPECTED)
    for name in found:
        profile = load_profile(BUS / f"{name}.toml")
        reference = load_profile(PROFILES / f"{name.split('-bus-')[0]}-"
                                 f"{'piecewise-pid' if name.startswith('fert') else 'fuzzy-pid'}"
                                 "-daemon.toml")
        assert profile.limits == reference.limits and profile.timing == reference.timing
        assert profile.rig_config == reference.rig_config


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_a_bus_defect_fails_its_measurement(name: str, tmp_path: Path) -> None:
    record, measurements = _lockstep_run(name, BUS, tmp_path, "inline")
    assert record["verdict"] != "error", record["error"]
    side = SIDE_EFFECTS.get(name.split("-bus-")[1].removesuffix("-daemon"), set())
    assert EXPECTED[name] <= _failing(measurements) <= EXPECTED[name] | side, [
        (m.name, m.value, m.conditions, m.note) for m in measurements
        if m.outcome is not Outcome.PASS]


@pytest.mark.parametrize("name", REFERENCES)
def test_the_reference_passes_every_measurement_in_lockstep(name: str, tmp_path: Path) -> None:
    record, measurements = _lockstep_run(name, PROFILES, tmp_path, "softbus")
    assert record["verdict"] != "error", record["error"]
    assert [e["kind"] for e in record["events"]].count("dut-restart") == 1
    names = {m.name for m in measurements}
    assert {"bus.undeclared_frames", "bus.dlc_errors", "bus.cycle_time.median",
            "bus.heartbeat.period", "bus.bootup.unexpected", "bus.share"} <= names
    bad = [(m.name, m.value, m.conditions, m.note) for m in measurements
           if m.outcome is not Outcome.PASS]
    assert not bad
    # issue 20.6: cantools knows every frame of the run (the drive's are its EDS's)
    log = read_bus_log(tmp_path / "bus.log")
    known = {m.frame_id for m in cantools.database.load_file(
        load_profile(PROFILES / f"{name}.toml").wiring.database).messages}
    unknown = {int(i) for i in log.can_id} - known
    if name.startswith("fertilizer"):
        assert not unknown, sorted(hex(i) for i in unknown)
    else:
        # the J1939 DBC: the CANopen frames are the drive's EDS's and CiA 301's (NMT, SYNC,
        # the controller's heartbeat)
        drive = {0x082, 0x182, 0x282, 0x382, 0x582, 0x702, 0x202, 0x302, 0x402, 0x602}
        assert unknown <= drive | {0x000, 0x080, 0x701}, sorted(hex(i) for i in unknown)


@pytest.mark.realtime
@pytest.mark.parametrize("name", REFERENCES)
def test_the_reference_passes_every_measurement_in_real_time(name: str, tmp_path: Path) -> None:
    load, cpus = os.getloadavg()[0], os.cpu_count() or 1
    if load > cpus:
        # the DUT's process and the software bus's relay then wait for a CPU for ms at a
        # time: the intervals and latencies measure the host, not the DUT
        pytest.skip(f"host overloaded (load {load:.1f} on {cpus} CPUs): real-time bus timing "
                    "would measure the host")
    profile = load_profile(PROFILES / f"{name}.toml")
    rig = load_rig(profile.dut.rig)
    scenario_name, duration = REALTIME[rig.name]
    scenario = _short(rig.load_scenario(scenario_name), duration, None)
    record, measurements = _run(profile, scenario, tmp_path, bus="softbus", clock="realtime")
    timing = record.get("timing") or {}
    if not timing.get("valid", True):
        pytest.skip("invalid bench: the rig's real-time timing was out of bounds (load)")
    assert record["verdict"] != "error", record["error"]
    assert {"bus.sync_latency.p50", "bus.sync_latency.p99", "bus.sync_latency.max"} <= \
        {m.name for m in measurements}
    bad = [(m.name, m.value, m.conditions, m.note) for m in measurements
           if m.outcome in (Outcome.FAIL, Outcome.ERROR)]
    assert not bad


def _qualify(profile: Path, out: Path, selection: str) -> dict:
    proc = subprocess.run(
        [sys.executable, "-m", "hil", "qualify", str(profile), "--bus", "inline",
         "--out", str(out), "-k", selection, "--quiet"],
        capture_output=True, text=True, cwd=ROOT, timeout=600)
    path = out / "record.json"
    assert path.exists(), proc.stdout + proc.stderr
    return json.loads(path.read_text())


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_a_bus_defect_passes_the_control_suites(name: str, tmp_path: Path) -> None:
    """The step suites in ``hil qualify``: every control measurement passes, the qualification
    fails on the defect's conformance measurement alone."""
    selection = "flow_step" if name.startswith("fertilizer") else "depth_step"
    record = _qualify(BUS / f"{name}.toml", tmp_path / "q", selection)
    control = [m for m in record["measurements"] if not m["name"].startswith("bus.")]
    failing = {m["name"] for m in record["measurements"] if m["outcome"] in ("fail", "error")}
    side = SIDE_EFFECTS.get(name.split("-bus-")[1].removesuffix("-daemon"), set())
    assert record["verdict"] == "fail" and EXPECTED[name] <= failing
    if name in CONTROL_CONSEQUENCES:
        return
    assert control and all(m["outcome"] in ("pass", "info") for m in control), control
    assert failing <= EXPECTED[name] | side
