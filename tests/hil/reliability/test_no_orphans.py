"""SIGKILL of ``hil run`` leaves no DUT process behind, nor a helper the DUT started in a
session of its own (issue #22.4, host side)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def _alive(pid: int) -> bool:
    """Running (a zombie waiting for a reaper that a container's PID 1 may never be is not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _wait_for(predicate, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return predicate()


def test_sigkill_of_hil_run_leaves_no_dut_behind(dying_profile, tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "hil", "run", "--dut",
                             str(dying_profile("child")), "--scenario", "bench-step-23",
                             "--clock", "realtime", "--out", str(out)], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    pids: dict[str, int] = {}

    def started() -> bool:
        # hil run stages its files until the run ends: the DUT's log is in --out/.run-*/
        log = next(out.glob(".run-*/dut.stdout.log"), None)
        if log is None:
            return False
        text = log.read_text()
        pids.update({k: int(v) for k, v in re.findall(r"(pid|helper) (\d+)", text)})
        return {"pid", "helper"} <= set(pids) and "ready" in text
    try:
        assert _wait_for(started, 60), proc.stderr.read() if proc.poll() is not None else ""
        assert _alive(pids["pid"]) and _alive(pids["helper"])
        time.sleep(1.0)                       # mid-run: the guardian has seen the helper
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    try:
        assert _wait_for(lambda: not _alive(pids["pid"]), 10), "the DUT outlived hil run"
        assert _wait_for(lambda: not _alive(pids["helper"]), 10), \
            "the DUT's helper (own session) outlived hil run"
    finally:
        for pid in pids.values():
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_a_stopped_dut_takes_its_escaped_helper_with_it(dying_profile, tmp_path: Path) -> None:
    import dataclasses

    from hil.dut.process import ProcessDut
    from hil.dut.profile import load_profile
    from hil.rig import RunOptions, run_scenario
    from plant_emulators.fertilizer.rig import FertilizerRig

    dut = ProcessDut(load_profile(dying_profile("child")), clock="lockstep",
                     log_dir=tmp_path / "dut")
    scenario = dataclasses.replace(FertilizerRig.load_scenario("bench-step-23"), duration_s=2.0)
    result = run_scenario(FertilizerRig, scenario, dut, RunOptions(
        out_dir=tmp_path / "run", bus="softbus", clock="lockstep"))
    assert not result.record["error"]
    helper = int(re.search(r"helper (\d+)", result.record["dut"]["stdout_tail"]).group(1))
    assert _wait_for(lambda: not _alive(helper), 5), "the escaped helper was left running"
    assert result.record["dut"]["killed_descendants"] >= 1
