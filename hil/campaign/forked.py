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
import gc
import multiprocessing
import os
import signal
import sys
from pathlib import Path

#: imported once by the fork server: everything a sample's pytest session imports before its
#: first scenario that costs time (modules a rig lacks are skipped by the fork server); the
#: rigs and their suites' helper modules are added by name from their entry points
#: (:func:`preload_modules`): the core names no rig
PRELOAD = (
    "numpy", "scipy.signal", "control", "cantools", "can", "canopen", "pytest",
    "_pytest.python", "_pytest.fixtures", "hil.pytest_plugin", "hil.rig", "hil.metrics",
    "hil.record", "hil.dut.factory", "hil.conformance", "reference_controllers.inprocess",
)


def preload_modules() -> list[str]:
    """:data:`PRELOAD`, every registered rig's module and its suites' helper modules.

    The rigs come from the ``agrihil.rigs`` entry points, the suites from ``agrihil.suites``:
    each suite package's modules that are not test files (trace readers, pairing helpers),
    and those of the package above it (shared helpers such as a loaded-bus fixture).
    """
    import importlib.util
    import pkgutil
    from importlib.metadata import entry_points

    names = list(PRELOAD)
    names += [ep.value.partition(":")[0] for ep in entry_points(group="agrihil.rigs")]
    for ep in entry_points(group="agrihil.suites"):
        package = ep.value.partition(":")[0]
        parent = package.rpartition(".")[0]
        for owner in filter(None, (package, parent)):
            spec = importlib.util.find_spec(owner)
            if spec is None or not spec.submodule_search_locations:
                continue
            names += [f"{owner}.{m.name}"
                      for m in pkgutil.iter_modules(spec.submodule_search_locations)
                      if not m.ispkg and not m.name.startswith(("test_", "conftest"))]
    return list(dict.fromkeys(names))


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
        context.set_forkserver_preload(preload_modules())
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

    # what the fork server holds (the preloaded modules) is never garbage: the sample's
    # collections skip it (a splice of lists, O(1)); ~0.16 s of CPU less per depth sample
    gc.freeze()
    code = pytest.main(argv)
    from hil.rig import checkpoint

    checkpoint.release_all()    # the runs' held copies end with the sample, waited for here
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
