"""Isolation ``fork``: each sample in a fresh process forked from a server that has imported
the suites' dependencies once.

Why (measured, docs/guide/campaigns.md "Figures"): a fresh interpreter per sample spends
~1.8 s of CPU before its first scenario (interpreter start, pytest's plugins, numpy, scipy
via python-control, cantools, canopen, the rig and the suite's helpers), about 40 % of a
fertilizer firmware sample. A process forked from a process that already holds those
modules starts in milliseconds and is still a process of its own: its memory goes with it,
a hung sample is killed with its process group, a crash is the sample's error, not the
worker's.

This is the standard library's fork server (:mod:`multiprocessing`'s ``forkserver`` start
method with ``set_forkserver_preload``), not a home-made one: the server is a single-threaded
process started from the worker, so forking it is safe where forking the multi-threaded Dask
worker is not. ``multiprocessing`` refuses to start children from a *daemonic* process, and
``dask worker`` starts daemonic workers by default: the embedded cluster starts its workers
non-daemonic (``distributed.worker.daemon = False``); on another cluster start the workers
with ``DASK_DISTRIBUTED__WORKER__DAEMON=False`` or choose ``--isolation process``.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
from pathlib import Path

#: imported once by the fork server: everything a sample's pytest session imports before its
#: first scenario that costs time (modules a rig lacks are skipped by the fork server)
PRELOAD = (
    "numpy", "scipy.signal", "control", "cantools", "can", "canopen", "pytest",
    "_pytest.python", "_pytest.fixtures", "hil.pytest_plugin", "hil.rig", "hil.metrics",
    "hil.record", "hil.dut.factory", "hil.conformance", "plant_emulators.fertilizer.rig",
    "plant_emulators.sowing_depth.rig", "reference_controllers.inprocess",
    "test_suites.fertilizer.traces", "test_suites.sowing_depth.traces",
    "test_suites.sowing_depth.pairing", "test_suites.loaded_bus",
)


class ForkRefused(RuntimeError):
    """This worker cannot fork samples (a daemonic process may not have children)."""


_context: multiprocessing.context.ForkServerContext | None = None


def _fork_context() -> multiprocessing.context.ForkServerContext:
    global _context
    if multiprocessing.current_process().daemon:
        raise ForkRefused(
            "--isolation fork: this Dask worker is a daemonic process, which may not start "
            "processes; start the workers with DASK_DISTRIBUTED__WORKER__DAEMON=False or "
            "choose --isolation process")
    if _context is None:
        # the fork server inherits this environment when it starts: the samples hash
        # strings as a fresh process per sample does
        os.environ["PYTHONHASHSEED"] = "0"
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(list(PRELOAD))
        _context = context
    return _context


def _sample_main(argv: list[str], log: str) -> None:
    """The forked sample: its own session and process group, its output to ``log``."""
    os.setsid()
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    for std in (1, 2):
        os.dup2(fd, std)
    os.close(fd)
    import pytest

    code = pytest.main(argv)
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(int(code))


def run_forked(argv: list[str], log: Path, timeout_s: float) -> int | None:
    """Run pytest with ``argv`` in a process forked from the fork server, its output to
    ``log``; its exit code (negative: killed by that signal), or None after ``timeout_s``,
    when it and its children have been killed."""
    process = _fork_context().Process(target=_sample_main, args=(argv, str(log)),
                                      name="agrihil-sample")
    process.start()
    try:
        process.join(timeout_s)
    except BaseException:
        _kill(process)
        raise
    if process.exitcode is None:
        _kill(process)
        return None
    return process.exitcode


def _kill(process: multiprocessing.process.BaseProcess) -> None:
    # the sample leads its own process group: its DUTs and buses go with it
    if process.pid is not None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(process.pid, signal.SIGKILL)
    process.kill()   # in case it was killed before it led its group
    process.join()
