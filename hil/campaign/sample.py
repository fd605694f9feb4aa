"""One campaign sample: the suites run once, in a fresh pytest process, in a private directory.

A sample is :class:`SampleTask` in, a plain ``dict`` out (:func:`run_sample`), so that it
travels to any Dask worker and back as is. The pytest process gets its own temporary
directory (its runs, record and traces), its own software bus on an ephemeral port (the rig
starts one per run) and its own DUT processes, in a process group of its own: a sample that
hangs past its timeout is killed with everything it started, and is returned as an error
sample with that reason. A fresh process per sample is the isolation: pytest's plugin and
module state never carries from one sample to the next (its cost is measured in
``benchmarks/bench_campaign.py``). The process is either a new interpreter (isolation
``process``) or forked from a server that imported the suites' dependencies once (``fork``,
:mod:`hil.campaign.forked`); ``inprocess`` runs pytest in the worker itself.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from hil.campaign.forked import ForkRefused, run_forked
from hil.campaign.overrides import format_override

#: what a sample keeps of each measurement
_KEEP = ("name", "conditions", "value", "unit", "low", "high", "outcome")


@dataclass(frozen=True)
class SampleTask:
    """Everything a worker needs to run sample ``index`` (paths absolute)."""

    profile: str
    index: int
    seed: int
    bus: str = "softbus"
    clock: str = "lockstep"
    suites: str = "fast"
    #: dispersed rig parameters, dotted key -> value
    overrides: dict[str, float] = field(default_factory=dict)
    #: "measurements" (a private temp dir, removed after) or "full" (kept in ``out_dir``)
    record: str = "measurements"
    out_dir: str = ""
    timeout_s: float = 600.0
    keyword: str | None = None
    #: "process": a fresh pytest process per sample (default; a hung sample is killed at
    #: ``timeout_s``); "inprocess": pytest.main in the worker itself (no interpreter start
    #: and no collection imports per sample, but no hard timeout: see docs/guide/campaigns.md)
    isolation: str = "process"

    def override_args(self) -> list[str]:
        return [format_override(k, v) for k, v in sorted(self.overrides.items())]

    def qualify_command(self) -> str:
        """The ``hil qualify`` command that reproduces this sample bit for bit."""
        parts = ["hil", "qualify", self.profile, "--bus", self.bus, "--clock", self.clock,
                 "--suite", self.suites, "--seed", str(self.seed)]
        rig_file = _rig_file_of_profile(self.profile)
        if rig_file is not None:      # a rig of your own is named by its file
            parts += ["--rig", str(rig_file)]
        for item in self.override_args():
            parts += ["--rig-override", item]
        if self.keyword:
            parts += ["-k", self.keyword]
        return " ".join(_quote(p) for p in parts)


def _rig_file_of_profile(profile: str) -> Path | None:
    """The rig file of the profile's rig when it is a rig of your own, else None."""
    from hil.dut.profile import load_profile
    from hil.rig.registry import rig_file_of

    return rig_file_of(load_profile(profile).dut.rig)


def _quote(text: str) -> str:
    import shlex

    return shlex.quote(text)


def pytest_argv(task: SampleTask, out: Path) -> list[str]:
    """The pytest command line of ``task`` writing into ``out``."""
    from hil.cli.suites import suite_location
    from hil.dut.profile import load_profile

    # the suites of the DUT's rig only, found through the agrihil.suites entry point
    root, ini = suite_location(load_profile(task.profile).dut.rig)
    argv = [sys.executable, "-m", "pytest", str(root), "-c", str(ini),
            "--rootdir", str(root), "-p", "no:cacheprovider", "-q", "--no-header",
            "--hil-dut", task.profile, "--hil-bus", task.bus, "--hil-clock", task.clock,
            "--hil-report", str(out), "--hil-suite", task.suites,
            "--hil-seed", str(task.seed), "--hil-record", task.record,
            # the suites use neither; Hypothesis' plugin alone takes ~0.6 s of CPU to import
            "-p", "no:hypothesispytest", "-p", "no:benchmark"]
    for item in task.override_args():
        argv += ["--hil-rig-override", item]
    if task.record == "full":
        argv += ["--junitxml", str(out / "junit.xml"), "-o", "junit_family=xunit2"]
    if task.keyword:
        argv += ["-k", task.keyword]
    return argv


def run_sample(task: SampleTask) -> dict[str, Any]:
    """Run ``task`` and return the sample: its measurements, verdict and reason, never raising
    for what happens inside the pytest process (a timeout or a crash is an ``error`` sample)."""
    t0 = time.perf_counter()
    keep = task.record == "full"
    if keep:
        out = Path(task.out_dir)
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir(parents=True)
        scratch = None
    else:
        scratch = tempfile.mkdtemp(prefix=f"agrihil-sample-{task.index}-")
        out = Path(scratch)
    sample: dict[str, Any] = {
        "index": task.index, "seed": task.seed, "overrides": dict(task.overrides),
        "verdict": "error", "error": None, "measurements": [], "failed_tests": [],
        "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        log = out / "pytest.log"
        if task.isolation == "inprocess":
            code = _run_inprocess(task, out, log)
            _read_record(sample, out / "record.json", code, log)
            return sample
        if task.isolation == "fork":
            try:
                forked = run_forked(_fork_argv(task, out), log, task.timeout_s)
            except ForkRefused as exc:
                sample["error"] = str(exc)
                return sample
            if forked is None:
                sample["error"] = (f"timeout: the sample ran longer than {task.timeout_s:g} s "
                                   f"and was killed")
                return sample
            _read_record(sample, out / "record.json", forked, log)
            return sample
        with log.open("wb") as fh:
            proc = subprocess.Popen(pytest_argv(task, out), stdout=fh, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL, start_new_session=True,
                                    env={**os.environ, "PYTHONHASHSEED": "0"})
            try:
                code = proc.wait(timeout=task.timeout_s)
            except subprocess.TimeoutExpired:
                _kill_group(proc)
                sample["error"] = (f"timeout: the sample ran longer than {task.timeout_s:g} s "
                                   f"and was killed")
                return sample
            except BaseException:
                _kill_group(proc)
                raise
        _read_record(sample, out / "record.json", code, log)
        return sample
    finally:
        sample["wall_s"] = round(time.perf_counter() - t0, 3)
        sample["rss_mb"] = _rss_mb()
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)


def _read_record(sample: dict[str, Any], path: Path, code: int, log: Path) -> None:
    if not path.exists():
        tail = log.read_text(errors="replace").strip().splitlines()[-6:]
        sample["error"] = (f"pytest exited {code} without a record: " + " | ".join(tail))[:800]
        return
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        sample["error"] = f"unreadable record {path.name}: {exc}"
        return
    sample["verdict"] = record.get("verdict", "error")
    sample["measurements"] = [{k: m.get(k) for k in _KEEP} for m in record["measurements"]]
    sample["failed_tests"] = [t["nodeid"] for t in record.get("tests", [])
                              if t.get("outcome") == "failed"]
    sample["sim_wall_s"] = record.get("wall_s")
    if sample["verdict"] in ("error", "invalid-bench"):
        errors = [r.get("error") for r in record.get("runs", []) if r.get("error")]
        sample["error"] = (f"qualification verdict {sample['verdict']}"
                           + (f": {errors[0]}" if errors else f" (pytest exit {code})"))


def _fork_argv(task: SampleTask, out: Path) -> list[str]:
    # the fork server imported the framework before pytest could rewrite its asserts (the
    # suites' own modules are still rewritten): say nothing about that in every sample's log
    return [*pytest_argv(task, out)[3:], "-W", "ignore::pytest.PytestAssertRewriteWarning"]


def _run_inprocess(task: SampleTask, out: Path, log: Path) -> int:
    """pytest.main in this process, its output to ``log``. Measured (bench_campaign.py and
    docs/guide/campaigns.md): the same seed gives the same measurements as in a fresh process
    and the worker's memory stays flat, so no state leaks into the results."""
    import contextlib

    import pytest

    argv = [*pytest_argv(task, out)[3:], "-p", "no:faulthandler"]
    with log.open("w") as fh, contextlib.redirect_stdout(fh), contextlib.redirect_stderr(fh):
        return int(pytest.main(argv))


def _kill_group(proc: subprocess.Popen[bytes]) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def _rss_mb() -> float:
    """Resident memory of this (worker) process, MB."""
    try:
        with open(f"/proc/{os.getpid()}/status") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    return round(int(line.split()[1]) / 1024, 1)
    except OSError:
        pass
    return 0.0


def task_dict(task: SampleTask) -> dict[str, Any]:
    return asdict(task)
