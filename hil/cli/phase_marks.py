"""The phases inside a qualification's pytest session (see :mod:`hil.cli.phases`); a module
of its own so that importing the ``hil`` command does not import pytest."""

from __future__ import annotations

import pytest

from hil.cli.phases import phase

__all__ = ["PhaseMarks"]


class PhaseMarks:
    """A pytest plugin marking the phases inside the suites: ``qualify:test`` as each test
    starts, ``qualify:record`` just before the session's record is written."""

    def pytest_runtest_call(self) -> None:
        phase("qualify:test")

    @pytest.hookimpl(tryfirst=True)     # before the qualification writes its record
    def pytest_sessionfinish(self) -> None:
        phase("qualify:record")
