"""Benchmarks are run on their own: ``python -m pytest benchmarks`` (or one file of it,
``benchmarks/bench_lockstep.py``); ``-s`` shows the figures the README quotes.

They never assert wall-clock targets (machines here are shared and noisy). Their files are
named ``bench_*.py`` so the test run (``testpaths = tests``, ``test_*.py``) never collects
them; this hook collects them when this directory is what pytest was asked to run.
"""

from __future__ import annotations

from pathlib import Path

import pytest


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Module | None:
    if (file_path.suffix != ".py" or not file_path.name.startswith("bench_")
            or parent.session.isinitpath(file_path)):     # named on the command line: pytest
        return None                                      # collects it already
    module: pytest.Module = pytest.Module.from_parent(parent, path=file_path)
    return module
