"""Process hygiene: a DUT process that crashes, hangs, stays silent, floods or leaves children
behind is handled, its output is kept, and nothing is left running."""

from __future__ import annotations

import time
from pathlib import Path

import can
import pytest

from hil.bus import open_bus
from hil.dut.base import DutError
from hil.dut.process import ProcessDut
from hil.dut.profile import load_profile
from hil.softbus import SoftwareBus

from .conftest import profile_text


def _group_alive(pgid: int) -> bool:
    """A live (not zombie) process is in group ``pgid`` (a zombie waits for a reaper that a
    container's PID 1 may never be: it runs nothing)."""
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            return True
    return False


@pytest.fixture
def softbus():
    with SoftwareBus(port=0) as sb:
        yield sb


def _dut(write_profile, tmp_path: Path, behaviour: str, **kw: object) -> ProcessDut:
    name = f"toy-{behaviour}-daemon"
    path = write_profile(name=name, text=profile_text(name, behaviour, **kw))  # type: ignore[arg-type]
    return ProcessDut(load_profile(path), clock="lockstep", log_dir=tmp_path / behaviour)


def test_good_dut_answers_sync_and_stops_cleanly(write_profile, tmp_path, softbus) -> None:
    dut = _dut(write_profile, tmp_path, "good")
    rig_bus = open_bus(softbus.spec())
    try:
        dut.start(softbus.spec(), {"AGRIHIL_GNSS_PORT": "/dev/null"})
        dut.check()
        rig_bus.send(can.Message(arbitration_id=0x080, data=[], is_extended_id=False))
        deadline = time.monotonic() + 5
        answer = None
        while time.monotonic() < deadline and answer is None:
            msg = rig_bus.recv(0.1)
            if msg is not None and msg.arbitration_id == 0x220:
                answer = msg
        assert answer is not None
        pid = dut.proc.pid  # type: ignore[union-attr]
        result = dut.stop()
    finally:
        rig_bus.shutdown()
    assert result["exit_code"] == 0 and not result["ignored_sigterm"]
    assert "ready" in result["stdout_tail"]
    assert Path(result["stdout"]).read_text().startswith("toy dut good starting")
    assert not _group_alive(pid)
    assert dut.stop() is result      # safe to call twice


def test_crash_is_reported_with_exit_status_and_stderr(write_profile, tmp_path, softbus) -> None:
    dut = _dut(write_profile, tmp_path, "crash")
    bus = open_bus(softbus.spec())
    try:
        dut.start(softbus.spec())
        bus.send(can.Message(arbitration_id=0x080, data=[], is_extended_id=False))
        deadline = time.monotonic() + 5
        while dut.proc.poll() is None and time.monotonic() < deadline:  # type: ignore[union-attr]
            time.sleep(0.02)
        with pytest.raises(DutError, match="exit status 3") as info:
            dut.check()
        assert "simulated crash" in str(info.value)
    finally:
        bus.shutdown()
        result = dut.stop()
    assert result["exited_before_stop"] and result["exit_code"] == 3
    assert "simulated crash" in result["stderr_tail"]


def test_dut_ignoring_sigterm_is_killed_and_recorded(write_profile, tmp_path, softbus) -> None:
    dut = _dut(write_profile, tmp_path, "hang", stop_timeout_s=0.5)
    dut.start(softbus.spec())
    pid = dut.proc.pid  # type: ignore[union-attr]
    t0 = time.monotonic()
    result = dut.stop()
    assert result["ignored_sigterm"] is True
    assert result["exit"] == "signal SIGKILL"
    assert time.monotonic() - t0 < 5
    assert not _group_alive(pid)


def test_silent_dut_fails_start_with_its_output(write_profile, tmp_path, softbus) -> None:
    name = "toy-silent-daemon"
    text = profile_text(name, "silent").replace("ready_timeout_s = 10.0", "ready_timeout_s = 1.0")
    dut = ProcessDut(load_profile(write_profile(name=name, text=text)), clock="lockstep",
                     log_dir=tmp_path / "silent")
    with pytest.raises(DutError, match=r"never came up: .* boot-up frame 0x710 within 1 s"):
        dut.start(softbus.spec())
    assert dut.proc is None           # stopped on the way out: nothing left behind
    assert "toy dut silent starting" in (tmp_path / "silent" / "dut.stdout.log").read_text()


def test_grandchildren_are_stopped_with_the_dut(write_profile, tmp_path, softbus) -> None:
    dut = _dut(write_profile, tmp_path, "child")
    dut.start(softbus.spec())
    pid = dut.proc.pid  # type: ignore[union-attr]
    time.sleep(0.2)
    assert _group_alive(pid)
    dut.stop()
    assert not _group_alive(pid)


def test_ready_on_stdout_line(write_profile, tmp_path, softbus) -> None:
    dut = _dut(write_profile, tmp_path, "good", ready="stdout:ready")
    dut.start(softbus.spec())
    try:
        assert dut.ready_s < 10
    finally:
        assert dut.stop()["exit_code"] == 0


def test_unstartable_command_names_the_profile(write_profile, tmp_path) -> None:
    name = "toy-missing-daemon"
    text = profile_text(name).replace('"{python}"', '"/nonexistent/firmware"')
    dut = ProcessDut(load_profile(write_profile(name=name, text=text)), clock="lockstep",
                     log_dir=tmp_path / "missing")
    with pytest.raises(DutError, match=r"\[launch.command\] cannot start"):
        dut.start("virtual:toy-missing")


@pytest.mark.parametrize(("behaviour", "ends"), [("flood", True), ("good", False)])
def test_a_flooding_dut_ends_the_run_with_a_clear_error_and_its_frames_kept(
        write_profile, tmp_path, behaviour: str, ends: bool) -> None:
    """500 frames per SYNC against a limit of 50 per control period: the run ends as an error
    naming the limit, the frames up to there are in the bus log; a good DUT runs to the end.

    The flood goes before the step-end frame: a flood *after* it straddles lockstep steps as
    the socket delivers it (the runner moves on at the step-end frame), and once ended a 1 s
    run as ``no-measurements`` under load, no control period having seen more than 50."""
    import dataclasses

    from hil.rig import RunOptions, run_scenario
    from plant_emulators.fertilizer.rig import FertilizerRig

    dut = _dut(write_profile, tmp_path, behaviour)
    scenario = dataclasses.replace(FertilizerRig.load_scenario("bench-step-23"), duration_s=1.0)
    out = tmp_path / "run"
    result = run_scenario(FertilizerRig, scenario, dut, RunOptions(
        out_dir=out, bus="softbus", clock="lockstep",
        max_dut_frames_per_period=dut.profile.timing.max_frames_per_period))
    error = result.record["error"] or ""
    if ends:
        assert result.verdict == "error"
        assert "flooded the bus: more than 50 frames within one control period" in error
        assert "timing.max_frames_per_period" in error
        assert (out / "bus.log").read_text().count(" 3F0#") >= 50   # kept up to the limit
    else:
        assert not error and result.sim_s == pytest.approx(1.0)
    assert result.record["dut"]["exit_code"] is not None      # stopped, nothing left behind


def test_a_dut_that_dies_in_real_time_ends_the_run_there(write_profile, tmp_path) -> None:
    """A real-time run checks the DUT once per control period: a crash 0.3 s in ends the run
    then (with the DUT's stderr in the error), not after the scenario's 3 s; traces are kept."""
    import dataclasses

    from hil.record import load_traces
    from hil.rig import RunOptions, run_scenario
    from plant_emulators.fertilizer.rig import FertilizerRig

    name = "toy-crash-soon-daemon"
    path = write_profile(name=name, text=profile_text(name, "crash-soon"))
    dut = ProcessDut(load_profile(path), clock="realtime", log_dir=tmp_path / "crash")
    scenario = dataclasses.replace(FertilizerRig.load_scenario("bench-step-23"), duration_s=3.0)
    out = tmp_path / "run"
    result = run_scenario(FertilizerRig, scenario, dut,
                          RunOptions(out_dir=out, bus="softbus", clock="realtime"))
    error = result.record["error"] or ""
    assert result.verdict == "error"
    assert "the DUT exited with exit status 3 at t = 0." in error
    assert "simulated crash" in error
    assert result.sim_s < 2.0                 # simulated time reached, not a wall-clock limit
    arrays, _ = load_traces(out / "traces.npz")
    assert arrays["time_s"].size > 10         # what was recorded up to the crash is kept
