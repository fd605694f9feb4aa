"""The FMU host: an FMU in a process of its own, so that one crashing in its C code (a
segmentation fault, abort(), exit()) or hanging fails its run as a dying DUT does, named, with
the run's bus log and traces written, instead of ending the rig's process.

The crashing FMU (tests/hil/fmi/crash_fmu) is a proportional flow controller that fails at a
chosen control period; its profile's [build] makes it with CMake into agrihil's build cache.
"""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path

import numpy as np
import pytest

from hil.dut.base import DutStopped
from hil.dut.factory import make_dut, profile_run_options
from hil.dut.fmu import FmuDut
from hil.dut.profile import load_profile
from hil.fmi.host import HostedController, decode_frames, encode_frames
from hil.rig.runner import RunOptions, RunResult, run_scenario
from plant_emulators.fertilizer.rig import FertilizerRig
from tests.helpers.hil_forkserver import HilForkServer

ROOT = Path(__file__).resolve().parents[3]
CRASH = Path(__file__).resolve().parent / "crash_fmu"
EXAMPLE = ROOT / "docs" / "examples" / "fmu-controller" / "minimal-fmu-controller.toml"
FMU_NAME = "agrihil-crash-fmu.fmu"
HOW = {"segv": 1, "abort": 2, "exit": 3, "hang": 4}


def crash_profile(tmp_path: Path, how: str = "segv", at_step: int = 0, *,
                  isolation: str = "process", timeout_s: float = 10.0) -> Path:
    """The crashing FMU's profile: built from crash_fmu/, failing at control period
    ``at_step`` (0: never)."""
    text = f'''
[dut]
name = "crash-fmu"
version = "0.1.0"
kind = "fmu"
rig = "fertilizer"
controller = "crash-p"

[build]
command = ["sh", "-c", "cmake -S {CRASH} -B {{build_dir}} && cmake --build {{build_dir}}"]
sources = ["{CRASH}/model.c", "{CRASH}/config.h", "{CRASH}/modelDescription.xml",
           "{CRASH}/CMakeLists.txt"]
artifacts = ["{{build_dir}}/{FMU_NAME}"]

[fmu]
path = "{{build_dir}}/{FMU_NAME}"
level = "signal"
isolation = "{isolation}"
host_timeout_s = {timeout_s}

[fmu.variables]
target = "target_flow"
flow = "row_flow[1]"
command = "motor_command"

[wiring]
node_id = 0x10
command_ids = [0x220]

[timing]
control_period_ms = 100

[parameters]
fail_at_step = {at_step}
fail_how = {HOW[how]}
'''
    folder = tmp_path / f"profile-{how}-{at_step}-{isolation}"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "crash-fmu.toml"
    path.write_text(text, encoding="utf-8")
    return path


def run(tmp: Path, profile_path: Path, seconds: float, bus: str = "inline") -> RunResult:
    profile = load_profile(profile_path)
    dut, _ = make_dut(profile, bus=bus, clock="lockstep", log_dir=tmp)
    sc = dataclasses.replace(FertilizerRig.load_scenario("bench-step-23"), duration_s=seconds)
    return run_scenario(FertilizerRig, sc, dut, RunOptions(
        out_dir=tmp, bus=bus, clock="lockstep", **profile_run_options(profile)))


def last_frame_time(bus_log: Path) -> float:
    """The time of the last frame in a candump-style bus log."""
    last = bus_log.read_text().strip().splitlines()[-1]
    return float(last.split()[0].strip("()"))


def test_frames_cross_to_the_host_and_back_unchanged() -> None:
    import can

    frames = [can.Message(arbitration_id=0x18FEF100, is_extended_id=True, data=b"\x01\x02",
                          timestamp=12.345678),
              can.Message(arbitration_id=0x7FF, is_remote_frame=True, dlc=8, data=b""),
              can.Message(arbitration_id=0x4, is_error_frame=True, is_extended_id=True,
                          data=b"\x00", is_rx=True),
              can.Message(arbitration_id=0x123, is_fd=True, bitrate_switch=True,
                          data=bytes(range(12)))]
    back = decode_frames(encode_frames(frames))
    for a, b in zip(frames, back, strict=True):
        assert a.equals(b, timestamp_delta=None, check_direction=True)
        assert a.timestamp == b.timestamp


def test_a_segfaulting_fmu_fails_its_run_named_with_bus_log_and_traces(tmp_path: Path) -> None:
    result = run(tmp_path / "run", crash_profile(tmp_path, "segv", 21), 5.0)
    assert result.verdict == "error"
    error = result.record["error"]
    assert error.startswith(f"the DUT crashed: the host process of FMU {FMU_NAME} died of "
                            f"SIGSEGV handling SYNC 21 at t = 2.0 s"), error
    assert result.record["dut_stopped"]["t_s"] == pytest.approx(2.0, abs=0.11)
    # what was recorded up to the crash is written: 2 s of frames, the traces to there
    bus_log = tmp_path / "run" / "bus.log"
    assert 1.9 <= last_frame_time(bus_log) <= 2.1
    with np.load(tmp_path / "run" / "traces.npz") as traces:
        assert 1.9 <= float(traces["time_s"][-1]) <= 2.1
    assert (tmp_path / "run" / "record.json").is_file()
    # the rig's process has no host left behind
    assert not [t for t in threading.enumerate() if t.name.startswith("fmu-host-")]


@pytest.mark.slow
@pytest.mark.parametrize(("how", "says"), [
    ("abort", "crashed: the host process of FMU {fmu} died of SIGABRT handling SYNC 11"),
    ("exit", "crashed: the host process of FMU {fmu} exited with exit status 3 handling "
             "SYNC 11"),
    ("hang", "stopped answering: FMU {fmu} took more than 1 s handling SYNC 11 (its host "
             "process was killed)"),
])
def test_an_fmu_that_aborts_exits_or_hangs_fails_its_run_named(
        tmp_path: Path, how: str, says: str) -> None:
    result = run(tmp_path / "run", crash_profile(tmp_path, how, 11, timeout_s=1.0), 3.0)
    assert result.verdict == "error"
    assert result.record["error"].startswith(
        "the DUT " + says.format(fmu=FMU_NAME) + " at t = 1.0 s"), result.record["error"]
    assert 0.9 <= last_frame_time(tmp_path / "run" / "bus.log") <= 1.1
    assert (tmp_path / "run" / "traces.npz").is_file()


@pytest.mark.slow
def test_on_the_software_bus_a_segfaulting_fmu_fails_its_run_named(tmp_path: Path) -> None:
    """On the software bus the FMU is driven from a thread of the rig's process: the host's
    death reaches the run through the DUT's check, as a dying DUT process's does."""
    result = run(tmp_path / "run", crash_profile(tmp_path, "segv", 11), 3.0, bus="softbus")
    assert result.verdict == "error"
    assert result.record["error"].startswith(
        f"the DUT crashed: the host process of FMU {FMU_NAME} died of SIGSEGV handling "
        f"SYNC 11 at t = 1."), result.record["error"]
    assert (tmp_path / "run" / "bus.log").stat().st_size > 0


@pytest.mark.slow
def test_hil_run_with_a_segfaulting_fmu_ends_as_with_a_dying_dut(
        tmp_path: Path, hil_forked: HilForkServer) -> None:
    """``hil run``: the same exit status as a DUT process that dies (1: the DUT stopped; see
    docs/guide/reliability.md), one line naming the FMU and when, no traceback, the run's
    files written."""
    profile = crash_profile(tmp_path, "segv", 11)
    load_profile(profile)          # built here once (the cache), not under the time limit
    out = tmp_path / "out"
    done = hil_forked.run(["run", "--dut", str(profile), "--scenario", "bench-step-23",
                           "--bus", "inline", "--out", str(out)], ROOT, timeout_s=300)
    assert done.returncode == 1, done.stderr[-2000:]
    assert f"hil: run failed: the DUT crashed: the host process of FMU {FMU_NAME} died of " \
           f"SIGSEGV handling SYNC 11 at t = 1.0 s" in done.stderr, done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    assert (out / "bus.log").stat().st_size > 0 and (out / "traces.npz").is_file()
    assert 0.9 <= last_frame_time(out / "bus.log") <= 1.1


def test_isolation_none_runs_in_process_with_the_same_bus_log(tmp_path: Path) -> None:
    """The host changes nothing of what the FMU does: the same bus log byte for byte."""
    logs = {}
    for isolation in ("process", "none"):
        profile = load_profile(crash_profile(tmp_path, "segv", 0, isolation=isolation))
        dut, _ = make_dut(profile, bus="inline", clock="lockstep")
        assert isinstance(dut, FmuDut)
        assert isinstance(dut.controller, HostedController) == (isolation == "process")
        assert dut.checkpointable == (isolation == "none")
        out = tmp_path / isolation
        sc = dataclasses.replace(FertilizerRig.load_scenario("bench-step-23"), duration_s=3.0)
        result = run_scenario(FertilizerRig, sc, dut, RunOptions(
            out_dir=out, bus="inline", clock="lockstep", **profile_run_options(profile)))
        assert not result.record["error"], result.record["error"]
        assert result.record["dut"]["fmu_isolation"]["isolation"] == isolation
        logs[isolation] = (out / "bus.log").read_bytes()
    assert logs["process"].count(b"\n") > 100
    assert logs["process"] == logs["none"]


def test_an_fmu_error_in_the_host_comes_back_with_its_text(fmus: Path) -> None:
    """An exception in the controller (here: CAN FD on the classic bus) is raised in the rig
    as it would be in process: the same type and text."""
    import can

    from tests.hil.fmi.test_bus_fmu import SYNC, controller

    inner = controller(fmus, fd_at_step=1)
    hosted = HostedController(inner, fmu=inner.fmu.path, timeout_s=10.0)
    dut = FmuDut(hosted, None, fmu_file=inner.fmu.path, level="bus")
    bus = dut.attach_inline()
    with pytest.raises(DutStopped, match=r"raised LsBusError: .*CAN FD transmit of id 0x1A1 "
                                         r"\(12 bytes\)"):
        bus.send(SYNC)
    assert isinstance(bus, can.BusABC)
    result = dut.stop()
    assert result["fmu_isolation"]["isolation"] == "process"
    assert hosted.pid is None                                     # the host has ended


def test_a_bad_host_timeout_is_refused_naming_the_key(tmp_path: Path) -> None:
    from hil.errors import ConfigError

    with pytest.raises(ConfigError, match=r"fmu\.host_timeout_s.*must be a number 0 < x"):
        load_profile(crash_profile(tmp_path, "segv", 0, timeout_s=0.0))


class _Fake:
    """A controller with no FMU: answers SYNC with 0x220, never answers 0x100 (its ``silent``
    frames), and raises on a 0x100 with data ``ff``."""

    name = "fake"

    def configure(self, env: dict[str, str]) -> None:
        self.env = env

    def on_start(self) -> list:
        import can

        return [can.Message(arbitration_id=0x710, data=b"\x00", is_extended_id=False)]

    def silent(self, msg) -> bool:
        return msg.arbitration_id == 0x100

    def on_frame(self, msg) -> list:
        import can

        if msg.arbitration_id == 0x100 and bytes(msg.data) == b"\xff":
            raise ZeroDivisionError("a bug in a silent frame")
        if msg.arbitration_id == 0x080:
            return [can.Message(arbitration_id=0x220, data=b"\x01", is_extended_id=False)]
        return []


def test_silent_frames_go_without_a_round_trip_and_their_errors_come_at_the_next() -> None:
    import can

    sync = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
    quiet = can.Message(arbitration_id=0x100, data=b"\x01", is_extended_id=False)
    bad = can.Message(arbitration_id=0x100, data=b"\xff", is_extended_id=False)
    hosted = HostedController(_Fake(), fmu=Path("fake.fmu"), timeout_s=10.0)  # type: ignore[arg-type]
    try:
        assert [m.arbitration_id for m in hosted.on_start()] == [0x710]
        assert hosted.on_frame(quiet) == [] and hosted.on_frame(quiet) == []
        assert [m.arbitration_id for m in hosted.on_frame(sync)] == [0x220]
        assert hosted.host_record()["round_trips"] == 2        # start and the SYNC
        assert hosted.on_frame(bad) == []
        with pytest.raises(ZeroDivisionError, match="a bug in a silent frame"):
            hosted.on_frame(sync)
        assert [m.arbitration_id for m in hosted.on_frame(sync)] == [0x220]   # told once
    finally:
        hosted.close()
    assert hosted.pid is None and hosted.host_record()["cpu_s"] is not None


def test_a_copy_of_the_rig_process_cannot_drive_its_host() -> None:
    """What a prefix checkpoint's fork of the rig would meet: a refusal, not a shared FMU."""
    import os

    import can

    hosted = HostedController(_Fake(), fmu=Path("fake.fmu"), timeout_s=10.0)  # type: ignore[arg-type]
    try:
        hosted.on_start()
        assert threading.active_count() > 1      # so hil.rig.checkpoint holds no run now
        pid = os.fork()
        if pid == 0:
            code = 3
            try:
                hosted.on_frame(can.Message(arbitration_id=0x080, is_extended_id=False))
            except DutStopped as exc:
                code = 0 if "copy of the rig's process" in str(exc) else 4
            finally:
                os._exit(code)
        assert os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) == 0
        assert hosted.on_frame(can.Message(arbitration_id=0x080, is_extended_id=False))
    finally:
        hosted.close()


@pytest.mark.slow
def test_a_hosted_lsbus_node_answers_and_records_as_in_process(fmus: Path) -> None:
    import can

    from tests.hil.fmi.test_bus_fmu import SYNC, controller

    rx = can.Message(arbitration_id=0x181, data=b"\x01\x02", is_extended_id=False)
    answers: dict[str, list[bytes]] = {}
    records = {}
    for where in ("host", "rig"):
        inner = controller(fmus)
        c = HostedController(inner, fmu=inner.fmu.path, timeout_s=10.0) if where == "host" \
            else inner
        try:
            got = [bytes(m.data) for m in c.on_start()]
            for _ in range(5):
                got += [bytes(m.data) for m in c.on_frame(SYNC) + c.on_frame(rx)]
            answers[where] = got
            records[where] = c.record()
        finally:
            c.close()
    assert len(answers["host"]) == 5 and answers["host"] == answers["rig"]
    assert records["host"] == records["rig"] and records["host"]["confirmed"] == 4
