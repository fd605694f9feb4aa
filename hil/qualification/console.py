"""What a qualification prints while it runs and at its end, as a pytest plugin of its own.

The session (:class:`hil.qualification.session.QualificationSession`) keeps the measurements
and decides the verdict; this plugin only prints them: under each test its control measurements
and one line for its bus conformance checks (:func:`hil.console.test_lines`), and at the end the
verdict with a one-screen summary (:func:`hil.console.summary_lines`) and how many measurements
were judged by a limit and how many were information only
(:func:`hil.qualification.summary.summary_line`). The lines themselves are formatted in
:mod:`hil.console` and :mod:`hil.qualification.summary`, so ``hil qualify`` and a plain
``pytest --hil-dut`` print the same.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import pytest

from hil.console import summary_lines, test_lines
from hil.qualification.summary import summary, summary_line

#: why report.html could not be written (set by the session, printed in the summary)
REPORT_ERROR = pytest.StashKey[str]()
#: the staging directory prefix of ``hil qualify``, which moves the outputs into its parent
STAGING_PREFIX = ".qualify-"


class _Session(Protocol):
    """What the console reads from the session."""

    measurements: list[dict[str, Any]]
    tests: list[dict[str, Any]]
    planned: list[str]
    report_dir: Path

    @property
    def name(self) -> str: ...

    def completed_tests(self) -> set[str]: ...

    def verdict(self) -> str: ...


class QualificationConsole:
    """Prints a qualification session (registered beside it by the plugin).

    Parameters
    ----------
    session : QualificationSession
        The session whose measurements and verdict are printed.
    config : pytest.Config
        pytest's configuration (verbosity, the terminal reporter).
    """

    def __init__(self, session: _Session, config: pytest.Config) -> None:
        self.session = session
        self.config = config

    @pytest.hookimpl(trylast=True)     # after the terminal's own PASSED/FAILED
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        """Print the test's measurements under its outcome line (verbose runs only).

        The control measurements one per line and one line for the bus conformance checks;
        every check with ``-vv``, the failed ones always.

        Parameters
        ----------
        report : pytest.TestReport
            The report of one phase of a test.
        """
        if report.when != "call":
            return
        terminal = self.config.pluginmanager.get_plugin("terminalreporter")
        if terminal is None or self.config.get_verbosity() < 1:
            return
        terminal.ensure_newline()
        mine = [m for m in self.session.measurements if m["test"] == report.nodeid]
        for line, bad in test_lines(mine, verbose=self.config.get_verbosity() >= 2):
            terminal.write_line("    " + line, red=bad)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        """Print the verdict, the one-screen summary and where the record is.

        Parameters
        ----------
        terminalreporter : TerminalReporter
            pytest's terminal reporter.
        """
        session = self.session
        error = terminalreporter.config.stash.get(REPORT_ERROR, None)
        terminalreporter.write_sep("=", f"agrihil qualification of {session.name}: "
                                        f"{session.verdict().upper()}")
        not_run = [n for n in session.planned if n not in session.completed_tests()]
        lines = summary_lines(session.measurements, session.tests, not_run=not_run)
        if session.measurements:   # after the counts: how many of them could fail the DUT
            lines.insert(1, summary_line(summary(session.measurements)))
        for line in lines:
            terminalreporter.write_line(line)
        # hil qualify writes into a staging directory and moves the result into its parent
        shown = (session.report_dir.parent
                 if session.report_dir.name.startswith(STAGING_PREFIX) else session.report_dir)
        terminalreporter.write_line(f"record: {shown / 'record.json'}")
        if error:
            terminalreporter.write_line(f"agrihil: ERROR: {error}", red=True)
