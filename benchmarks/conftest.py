"""Benchmarks are run on their own: ``python -m pytest benchmarks`` (or one file of it,
``benchmarks/bench_lockstep.py``); ``-s`` shows the figures the README quotes.

They never assert wall-clock targets (machines here are shared and noisy). Their files are
named ``bench_*.py`` so the test run (``testpaths = tests``, ``test_*.py``) never collects
them; this hook collects them when this directory is what pytest was asked to run.

``python -m pytest benchmarks --benchmark-disable`` is their smoke run: every benchmark runs
its code once, untimed, checks its results and skips its figures (:func:`timed_rounds`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Module | None:
    if (file_path.suffix != ".py" or not file_path.name.startswith("bench_")
            or parent.session.isinitpath(file_path)):     # named on the command line: pytest
        return None                                      # collects it already
    module: pytest.Module = pytest.Module.from_parent(parent, path=file_path)
    return module


@pytest.fixture
def timed_rounds(benchmark: Any) -> Callable[[], list[float]]:
    """Call it after ``benchmark.pedantic``: the timed rounds, in seconds.

    ``--benchmark-disable`` (pytest-benchmark runs the code once, untimed, and keeps no
    statistics) makes a smoke run of the benchmarks: the call skips the test there, after the
    code ran and after the checks made before the call, so each benchmark checks its results
    before it computes its figures."""
    def rounds() -> list[float]:
        if benchmark.stats is None:
            pytest.skip("--benchmark-disable: ran once untimed, its checks passed; no figure")
        return [float(t) for t in benchmark.stats.stats.data]
    return rounds
