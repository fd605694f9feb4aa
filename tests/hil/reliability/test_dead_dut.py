"""A DUT that dies, exits, raises, segfaults or hangs fails its run, named as such, in both
clocks (issues #21.3, #22.5, #22.6)."""

from __future__ import annotations

import dataclasses
import re
import time
from pathlib import Path

import can
import pytest

from hil.dut.inprocess import Controller, InProcessDut
from hil.dut.process import ProcessDut
from hil.dut.profile import load_profile
from hil.rig import RunOptions, run_scenario
from plant_emulators.fertilizer.rig import FertilizerRig

#: a lockstep step timeout far longer than any of these runs: a crash must not wait it out
LONG_TIMEOUT_S = 60.0


def _scenario(seconds: float = 5.0):
    return dataclasses.replace(FertilizerRig.load_scenario("bench-step-23"), duration_s=seconds)


def _run(profile: Path, tmp_path: Path, clock: str, seconds: float = 5.0, **kw):
    dut = ProcessDut(load_profile(profile), clock=clock, log_dir=tmp_path / "dut")
    t0 = time.monotonic()
    result = run_scenario(FertilizerRig, _scenario(seconds), dut, RunOptions(
        out_dir=tmp_path / "run", bus="softbus", clock=clock, **kw))
    return result, time.monotonic() - t0


@pytest.mark.parametrize(("how", "says"), [
    ("segv:20", "the DUT exited with SIGSEGV at t = 2.0 s"),
    ("exit0:20", "the DUT exited with exit status 0 at t = 2.0 s"),
    ("exit3:20", "the DUT exited with exit status 3 at t = 2.0 s"),
    ("raise:20", "the DUT exited with exit status 1 at t = 2.0 s"),
])
def test_a_dut_that_exits_in_lockstep_fails_the_run_at_once_named(
        dying_profile, tmp_path: Path, how: str, says: str) -> None:
    result, wall = _run(dying_profile(how), tmp_path, "lockstep",
                        step_timeout_s=LONG_TIMEOUT_S)
    assert result.verdict == "error"
    assert result.record["error"].startswith(says), result.record["error"]
    assert result.record["dut_stopped"]["t_s"] == pytest.approx(2.0, abs=0.11)
    assert wall < LONG_TIMEOUT_S / 2      # noticed by polling the process, not the timeout
    assert "dying_dut:" in result.record["error"]           # its last words are kept


def test_a_dut_that_hangs_in_lockstep_stopped_answering(dying_profile, tmp_path: Path) -> None:
    result, _ = _run(dying_profile("hang:20"), tmp_path, "lockstep", step_timeout_s=1.0)
    assert result.verdict == "error"
    assert result.record["error"].startswith("the DUT stopped answering at t = 2.0 s")


@pytest.mark.realtime
@pytest.mark.parametrize(("how", "says"), [
    # real time on a loaded machine: the SYNC the DUT dies at is the 21st, checked within a
    # control period or a few
    ("hang:20", r"the DUT stopped answering at t = (1\.9|2\.\d) s; no command frame"),
    ("segv:20", r"the DUT exited with SIGSEGV at t = (1\.9|2\.\d|3\.\d) s"),
])
def test_a_dut_that_stops_in_real_time_fails_the_run(dying_profile, tmp_path: Path, how: str,
                                                     says: str) -> None:
    # a silence limit of 2.5 s: a DUT process starved by a loaded machine is not "hung"
    result, _ = _run(dying_profile(how), tmp_path, "realtime", seconds=8.0,
                     step_timeout_s=2.5)
    assert result.verdict == "error", result.record["error"]
    assert re.match(says, result.record["error"]), result.record["error"]
    assert result.sim_s < 7.5              # the run ended there, not at the scenario's end


class _ExitsAfter(Controller):
    """An in-process controller that answers a few SYNCs, then calls ``sys.exit(0)``."""

    name = "exits-in-process"

    def __init__(self, syncs: int, exc: BaseException) -> None:
        self.left = syncs
        self.exc = exc

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.arbitration_id != 0x080:
            return []
        self.left -= 1
        if self.left < 0:
            raise self.exc
        return [can.Message(arbitration_id=0x220, data=[0, 0, 0, 0], is_extended_id=False)]


@pytest.mark.parametrize("bus", ["inline", "softbus"])
@pytest.mark.parametrize(("exc", "says"), [
    (SystemExit(0), "the DUT exited (SystemExit(0) in-process) at t = 1.0 s"),
    (ZeroDivisionError("x"), "the DUT raised ZeroDivisionError: x at t = 1.0 s"),
])
def test_an_in_process_controller_that_exits_fails_its_run(tmp_path: Path, bus: str,
                                                           exc: BaseException,
                                                           says: str) -> None:
    dut = InProcessDut(_ExitsAfter(10, exc))
    result = run_scenario(FertilizerRig, _scenario(), dut, RunOptions(
        out_dir=tmp_path / "run", bus=bus, clock="lockstep", step_timeout_s=LONG_TIMEOUT_S))
    assert result.verdict == "error"
    assert result.record["error"].startswith(says), result.record["error"]


def test_a_dut_dead_before_it_came_up_is_a_failed_run_not_a_setup_error(
        dying_profile, tmp_path: Path) -> None:
    class _Dead(Controller):
        name = "dead-on-arrival"

        def on_frame(self, msg: can.Message) -> list[can.Message]:
            return []

        def on_start(self) -> list[can.Message]:
            raise SystemExit(0)

    result = run_scenario(FertilizerRig, _scenario(), InProcessDut(_Dead()), RunOptions(
        out_dir=tmp_path / "run", bus="inline", clock="lockstep"))
    assert result.verdict == "error"
    assert result.record["error"].startswith("the DUT exited (SystemExit(0) in-process) at "
                                             "t = 0.0 s")
