"""A suite test's outcome from its measurements, as a pytest plugin of its own.

A test passes when its body passes *and* none of its measurements failed: a passing test with
a failed or errored measurement is reported failed, listing them; a test whose real-time run
had invalid timing is reported skipped (invalid bench, never a DUT failure); a test whose DUT
stopped fails with that reason rather than with what its code raised computing on the short
traces, and the measurements it did not get to are recorded as failed. The measurements also
become junit.xml properties.
"""

from __future__ import annotations

import inspect
import math
import re
from collections.abc import Generator
from typing import Any, Protocol

import pytest

from hil.console import conditions_text
from hil.limits import known_measurement
from hil.measurements import Measurement, Outcome
from hil.rig import RunResult


class _Session(Protocol):
    """What the outcomes read and record of the session."""

    invalid_bench: dict[str, str]
    dut_failures: dict[str, str]

    def measurements_of(self, nodeid: str) -> list[Measurement]: ...
    def dead_dut_reason(self, nodeid: str) -> str | None: ...
    def first_dead_run(self, nodeid: str) -> RunResult | None: ...
    def measure(self, nodeid: str, name: str, value: float, *,
                conditions: dict[str, Any] | None = None, run: RunResult | None = None,
                note: str = "") -> Measurement: ...

    @property
    def rig(self) -> str: ...


class TestOutcomes:
    """Judges each test of a qualification session (registered beside it by the plugin).

    Parameters
    ----------
    session : QualificationSession
        The session whose measurements judge the tests.
    """

    __test__ = False     # not a test class, whatever its name

    def __init__(self, session: _Session) -> None:
        self.session = session

    @pytest.hookimpl(wrapper=True)
    def pytest_pyfunc_call(self, pyfuncitem: pytest.Function) -> Generator[None, Any, Any]:
        """Fail a test whose DUT stopped with that reason, not with what its code raised.

        What the test's code raised computing on the short traces is not a suite error (and is
        not shown).
        """
        try:
            return (yield)
        except Exception as exc:
            reason = self.session.dead_dut_reason(pyfuncitem.nodeid)
            if reason is None:
                raise
            self.session.dut_failures[pyfuncitem.nodeid] = reason
            failed = self._fail_unmeasured(pyfuncitem)
            message = (f"{reason}; the test could not compute its measurements "
                       f"({type(exc).__name__}: {exc})"
                       + (f"; recorded as failed: {', '.join(failed)}" if failed else ""))
        pytest.fail(message, pytrace=False)    # outside the except: no exception chain

    def _fail_unmeasured(self, item: pytest.Function) -> list[str]:
        """Record as failed the measurements a test whose DUT stopped did not get to.

        Each is NaN with the reason: the catalogue names its code names (literally or as a
        parameter), with the test's other parameters as conditions (the suites' convention).
        """
        session = self.session
        names, conditions = unmeasured_names(item, session.rig)
        done = {m.name for m in session.measurements_of(item.nodeid)}
        dead = session.first_dead_run(item.nodeid)
        failed = []
        for name in names:
            if name not in done:
                session.measure(item.nodeid, name, math.nan, conditions=conditions, run=dead)
                failed.append(name)
        return failed

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_makereport(self, item: pytest.Item,
                                  call: pytest.CallInfo[None]) -> Generator[None, Any, None]:
        """Turn a test's judged measurements into its outcome.

        The measurements become junit.xml properties; a test whose run had invalid real-time
        timing is reported skipped (invalid bench), and a passing test with a failed or errored
        measurement is reported failed, listing those measurements.

        Parameters
        ----------
        item : pytest.Item
            The test.
        call : pytest.CallInfo
            The call phase's information.

        Yields
        ------
        None
            Control to the other hook implementations, which build the report.
        """
        outcome = yield
        report: pytest.TestReport = outcome.get_result()
        if report.when != "call":
            return
        session = self.session
        measured = session.measurements_of(item.nodeid)
        for m in measured:    # junit.xml <property> elements (junitxml reads them at teardown)
            item.user_properties.append((f"{m.name}{conditions_text(m.conditions)}",
                                         f"{m.value:g} {m.unit} ({m.outcome.value})"))
        if item.nodeid in session.invalid_bench and report.outcome != "skipped":
            report.outcome = "skipped"
            report.longrepr = (str(item.path), item.location[1] or 0,
                               "invalid bench: the rig's real-time timing was out of bounds "
                               f"({session.invalid_bench[item.nodeid]}); says nothing about "
                               "the DUT")
            return
        bad = [m for m in measured if m.outcome in (Outcome.FAIL, Outcome.ERROR)]
        if bad and report.outcome == "passed":
            report.outcome = "failed"
            lines = [f"{m.name}{conditions_text(m.conditions)} = {m.value:g} {m.unit}: "
                     f"{m.outcome.value} (limits {m.low} .. {m.high})"
                     + (f" - {m.note}" if m.note else "") for m in bad]
            report.longrepr = "measurements out of limits:\n  " + "\n  ".join(lines)


def unmeasured_names(item: pytest.Function, rig: str) -> tuple[list[str], dict[str, Any]]:
    """The catalogue measurements a test makes, and the conditions it makes them under.

    Its names: those its source passes to ``hil_measure`` literally and its string parameters
    that name a catalogue measurement of ``rig``; its conditions: its other parameters (numbers,
    flags, strings that name no measurement), less a ``scenario`` name.
    """
    params = dict(getattr(getattr(item, "callspec", None), "params", {}) or {})
    try:
        source = inspect.getsource(item.obj)
    except (OSError, TypeError):
        source = ""
    names = [n for n in re.findall(r"""hil_measure\(\s*["']([\w.]+)["']""", source)]
    names += [v for v in params.values() if isinstance(v, str)]
    names = [n for n in dict.fromkeys(names) if known_measurement(n, rig)]
    conditions = {k: v for k, v in params.items()
                  if isinstance(v, int | float | bool) or (isinstance(v, str)
                                                           and v not in names)}
    conditions = {k: v for k, v in conditions.items()
                  if not (isinstance(v, str) and k == "scenario")}
    return names, conditions
