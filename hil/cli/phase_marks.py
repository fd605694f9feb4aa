"""The phases inside a qualification's pytest session (see :mod:`hil.cli.phases`); a module
of its own so that importing the ``hil`` command does not import pytest."""

from __future__ import annotations

import pytest

from hil.cli.phases import phase

__all__ = ["OneDuration", "PhaseMarks"]


class PhaseMarks:
    """A pytest plugin marking the phases inside the suites: ``qualify:test`` as each test
    starts, ``qualify:record`` just before the session's record is written."""

    def pytest_runtest_call(self) -> None:
        phase("qualify:test")

    @pytest.hookimpl(tryfirst=True)     # before the qualification writes its record
    def pytest_sessionfinish(self) -> None:
        phase("qualify:record")


class OneDuration:
    """A pytest plugin for ``hil qualify``: pytest's last line counts the tests without its own
    session time, so the one duration the console prints is the command's wall time (which
    ``hil qualify`` prints last; issue 31.7: three durations for one run said three things)."""

    @pytest.hookimpl(trylast=True)
    def pytest_configure(self, config: pytest.Config) -> None:
        reporter = config.pluginmanager.get_plugin("terminalreporter")
        if reporter is None:
            return

        def counts_only() -> None:
            if reporter.verbosity < -1:
                return
            parts, colour = reporter.build_summary_stats_line()
            reporter.write_line(", ".join(text for text, _ in parts), **{colour: True})

        reporter.summary_stats = counts_only
