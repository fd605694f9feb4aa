"""The qualification session: one pytest run qualifying one DUT, from its first run to its
record.

:class:`QualificationSession` holds what the session collects and puts the pieces together:
it starts and caches the scenario runs (:mod:`hil.qualification.runs`), judges each run's bus
conformance (:mod:`hil.qualification.conformance_runs`), judges and keeps the suites'
measurements (:mod:`hil.qualification.measurements`), logs each test's outcome, and at the end
writes the record (:mod:`hil.qualification.record`) with its verdict
(:mod:`hil.qualification.verdict`). The pytest plugin (:mod:`hil.pytest_plugin`) makes it from
the ``--hil-*`` options and registers it with the plugins that print it
(:mod:`hil.qualification.console`) and turn its measurements into test outcomes
(:mod:`hil.qualification.outcomes`).
"""

from __future__ import annotations

import datetime as dt
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from hil.dut.factory import make_dut, profile_run_options
from hil.dut.physical import RESTART_SKIP_REASON, PhysicalDutSetupError
from hil.dut.profile import DutProfile
from hil.isobus.vt.steps import OperatorScriptError
from hil.measurements import Measurement
from hil.qualification.conformance_runs import judge_conformance
from hil.qualification.console import REPORT_ERROR
from hil.qualification.measurements import MeasurementBook
from hil.qualification.record import Completeness, qualification_record, write_outputs
from hil.qualification.runs import RunCache, RunEntry, run_dir, run_key, stopped_reason
from hil.qualification.suites import wanted_suites
from hil.qualification.verdict import session_verdict
from hil.rig import Rig, RunOptions, RunResult, run_scenario
from hil.rig.runner import CommandIdsError
from hil.rig.scenario import Scenario


@dataclass
class QualificationSession:
    """Everything one qualification collects; written out at the end of the session.

    Parameters
    ----------
    profile : DutProfile
        The DUT under qualification.
    bus, clock : str
        The bus spec and clock of its runs (``--hil-bus``, ``--hil-clock``).
    report_dir : Path
        Where runs, ``record.json`` and ``report.html`` go (``--hil-report``).
    seed : int, optional
        Added to every scenario's seed (``--hil-seed``).
    suites : str, optional
        The ``--hil-suite`` selection (comma-separated, ``all``).
    rig_overrides : dict, optional
        Rig config overrides on top of the profile's ``[rig]`` (``--hil-rig-override``).
    record_mode : str, optional
        ``full`` or ``measurements`` (no bus logs, traces files or ``report.html``).
    """

    profile: DutProfile
    bus: str
    clock: str
    report_dir: Path
    seed: int | None
    suites: str = "all"
    #: rig config overrides on top of the profile's [rig] (--hil-rig-override)
    rig_overrides: dict[str, Any] = field(default_factory=dict)
    #: "full" or "measurements" (no bus logs, no report.html)
    record_mode: str = "full"
    run_id: str = field(default_factory=lambda: uuid.uuid4().hex[:12])
    started_at: str = field(
        default_factory=lambda: dt.datetime.now(dt.UTC).isoformat(timespec="seconds"))
    t0: float = field(default_factory=time.perf_counter)
    tests: list[dict[str, Any]] = field(default_factory=list)
    invalid_bench: dict[str, str] = field(default_factory=dict)
    #: node ids of the tests selected to run (set when collection finishes)
    planned: list[str] = field(default_factory=list)
    #: a SIGINT/SIGTERM (KeyboardInterrupt) ended the session early
    interrupted: bool = False
    #: tests failed because their DUT stopped (node id -> "the DUT stopped at t = … s")
    dut_failures: dict[str, str] = field(default_factory=dict)
    #: a setup problem that ends the session (a physical ECU that is not on the bus)
    setup_error: str = ""
    #: the scenario runs (cached) and which test used which
    run_cache: RunCache = field(default_factory=RunCache)
    #: the judged measurements (made in __post_init__: they judge by the profile's limits)
    book: MeasurementBook = field(init=False)

    def __post_init__(self) -> None:
        self.book = MeasurementBook(self.profile)

    # --- what the record and the console read ---------------------------------------------------
    @property
    def name(self) -> str:
        """The name of the DUT under qualification."""
        return self.profile.name

    @property
    def rig(self) -> str:
        """The DUT's rig as the catalogue names it (``sowing_depth``)."""
        return self.book.rig

    @property
    def measurements(self) -> list[dict[str, Any]]:
        """The record's ``measurements`` so far (each with its ``test`` and ``run``)."""
        return self.book.entries

    @property
    def runs(self) -> dict[tuple[Any, ...], RunEntry]:
        """The session's runs by cache key."""
        return self.run_cache.entries

    @property
    def runs_of_test(self) -> dict[str, list[RunResult]]:
        """The runs each test used (node id -> results)."""
        return self.run_cache.of_test

    @property
    def by_item(self) -> dict[str, list[Measurement]]:
        """The judged measurements of each test (node id -> measurements)."""
        return self.book.by_test

    # --- runs ---------------------------------------------------------------------------------
    def run(self, nodeid: str, rig_cls: type[Rig], scenario: Scenario | str, *,
            label: str = "", seed: int | None = None, profile: DutProfile | None = None,
            bus: str | None = None, clock: str | None = None,
            step_timeout_s: float = 5.0) -> RunResult:
        """One scenario run of ``profile`` (default: the DUT under qualification), cached.

        Parameters
        ----------
        nodeid : str
            The node id of the test the run is for (it names the run's directory).
        rig_cls : type of Rig
            The rig to run.
        scenario : Scenario or str
            The scenario, or the name of one of the rig's packaged scenarios.
        label : str, optional
            Tells apart several runs of one test in the run's directory name.
        seed : int, optional
            The run's seed (default: the scenario's); ``--hil-seed`` is added to it.
        profile : DutProfile, optional
            The DUT to run (default: the DUT under qualification, e.g. another for a baseline).
        bus, clock : str, optional
            Override the session's (a suite that only means something in real time, such as
            bus load, runs real time even in a lockstep qualification).
        step_timeout_s : float, optional
            How long the DUT may stay silent before it counts as stopped answering (s).

        Returns
        -------
        RunResult
            The run's result; the same object for a repeated run with the same key (scenario,
            seed, DUT, bus and clock).
        """
        profile = profile or self.profile
        clock = clock or self.clock
        if isinstance(scenario, str):
            scenario = rig_cls.load_scenario(scenario)
        base = scenario.seed if seed is None else seed
        seed_used = base + (self.seed or 0)
        bus = bus or self.bus
        key = run_key(rig_cls, scenario, seed_used, profile, bus, clock)
        cached = self.run_cache.get(key, nodeid)
        if cached is not None:
            return cached
        if profile.dut.kind == "physical" and any(e.dut == "restart" for e in scenario.events):
            pytest.skip(RESTART_SKIP_REASON.format(scenario=scenario.name))
        rel = run_dir(nodeid, label)
        out_dir = self.report_dir / rel
        dut, build = make_dut(profile, bus=bus, clock=clock, log_dir=out_dir)
        # the rig is wired as the DUT under qualification says (a baseline run too)
        wiring = profile_run_options(profile, rig_from=self.profile)
        if self.rig_overrides:
            from hil.config import merge_tables

            wiring["rig_config"] = merge_tables(wiring["rig_config"], self.rig_overrides)
        try:
            result = run_scenario(rig_cls, scenario, dut, RunOptions(
                out_dir=out_dir, clock=clock, bus=bus, seed=seed_used,
                step_timeout_s=step_timeout_s, record_bus=self.record_mode == "full",
                save_traces=self.record_mode == "full",
                **wiring,
                extra_meta={"dut_identity": profile.identity(), "dut_build": build,
                            "test": nodeid}))
        except (PhysicalDutSetupError, CommandIdsError, OperatorScriptError) as exc:
            # not a verdict on the ECU (nor a scenario's operator script naming an object the
            # implement's pool lacks): the qualification stops as a setup error (exit 2)
            self.setup_error = str(exc)
            pytest.exit(f"setup error: {exc}", returncode=2)
        self.run_cache.add(key, RunEntry(result, rel, scenario.name))
        # bus conformance of the DUT under qualification, from the run's bus log (a
        # measurements-only campaign sample keeps none: its full reruns carry conformance)
        if profile is self.profile and self.record_mode == "full":
            for m in judge_conformance(self.profile, rig_cls, result, rel):
                self.book.keep(nodeid, m, rel)
        self.run_cache.used(nodeid, result)
        timing = result.record.get("timing") or {}
        if timing.get("mode") == "realtime" and not timing.get("valid", True):
            self.invalid_bench[nodeid] = rel
        return result

    def run_dir_of(self, result: RunResult) -> str:
        """The report-relative directory (``runs/...``) a run of this session wrote to.

        Parameters
        ----------
        result : RunResult
            A run returned by :meth:`run`.

        Returns
        -------
        str
            Its directory relative to the report directory, or ``""`` if the run is not this
            session's.
        """
        return self.run_cache.dir_of(result)

    def dead_dut_reason(self, nodeid: str) -> str | None:
        """Why a test's runs say nothing about its measurements (its DUT stopped), or None."""
        return self.run_cache.dead_dut_reason(nodeid)

    def first_dead_run(self, nodeid: str) -> RunResult | None:
        """The first run of the test ``nodeid`` that its DUT ended, or None."""
        return self.run_cache.first_dead(nodeid)

    # --- measurements ---------------------------------------------------------------------------
    def measure(self, nodeid: str, name: str, value: float, *,
                conditions: dict[str, Any] | None = None, run: RunResult | None = None,
                note: str = "") -> Measurement:
        """Judge one measurement against the profile's limits and keep it for the record.

        The limit is the profile's ``[limits]`` entry for ``name`` (its first ``when`` case that
        matches ``conditions``, else its band), else the catalogue's default (likewise): see
        :func:`hil.limits.applied_limit`; the measurement's ``limit_source`` says which. A case
        that names a condition the measurement does not carry (or a value of another kind)
        makes the measurement an error naming the profile's key.

        Parameters
        ----------
        nodeid : str
            The node id of the test that measured.
        name : str
            The measurement's name in the catalogue (:mod:`hil.limits`).
        value : float
            The measured value, in the catalogue's unit.
        conditions : dict, optional
            The conditions the value was measured under (scenario parameters and the like).
        run : RunResult, optional
            The run the value comes from. If the DUT stopped in that run, the value is recorded as
            NaN (failed) with the reason in the note.
        note : str, optional
            A remark kept with the measurement.

        Returns
        -------
        Measurement
            The judged measurement.

        Raises
        ------
        ConfigError
            ``name`` is not in the catalogue for the DUT's rig.
        """
        if run is not None and run.record.get("error"):
            value = float("nan")
            note = stopped_reason(run) + (f"; {note}" if note else "")
        m = self.book.judge(nodeid, name, value, conditions=conditions, note=note)
        return self.book.keep(nodeid, m, self.run_dir_of(run) if run is not None else "")

    def measurements_of(self, nodeid: str) -> list[Measurement]:
        """The measurements the test ``nodeid`` made (so far)."""
        return self.book.of_test(nodeid)

    # --- pytest hooks: the session's course ------------------------------------------------------
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        """Log the test's outcome for the record.

        The console prints it (:mod:`hil.qualification.console`).

        Parameters
        ----------
        report : pytest.TestReport
            The report of one phase of a test.
        """
        if report.when == "call" or (report.when == "setup" and report.outcome != "passed"):
            message = ""
            if report.outcome != "passed" and report.longrepr is not None:
                message = (report.longrepr[2] if isinstance(report.longrepr, tuple)
                           else str(report.longrepr))[-2000:]
            self.tests.append({"nodeid": report.nodeid, "outcome": report.outcome,
                               "duration_s": round(report.duration, 3), "message": message})

    def pytest_collection_finish(self, session: pytest.Session) -> None:
        """Remember the tests selected to run, to tell later whether the session completed.

        Parameters
        ----------
        session : pytest.Session
            The pytest session.
        """
        self.planned = [item.nodeid for item in session.items]

    def pytest_keyboard_interrupt(self, excinfo: Any) -> None:
        """Mark the session interrupted (SIGINT or SIGTERM), so its record says so.

        Parameters
        ----------
        excinfo : ExceptionInfo
            The interrupt, unused.
        """
        self.interrupted = True

    def pytest_sessionfinish(self, session: pytest.Session, exitstatus: int) -> None:
        """Write ``record.json`` (atomically) and ``report.html`` into the report directory.

        A failure to write the HTML report does not lose the record; it is reported in the
        terminal summary.

        Parameters
        ----------
        session : pytest.Session
            The pytest session.
        exitstatus : int
            pytest's exit status.
        """
        error = write_outputs(self.report_dir, self.record(exitstatus),
                              html=self.record_mode != "measurements")
        if error:
            session.config.stash[REPORT_ERROR] = error

    # --- the verdict and the record ---------------------------------------------------------------
    def completed_tests(self) -> set[str]:
        """Node ids of the tests that ran to their end (passed, failed or skipped)."""
        return {t["nodeid"] for t in self.tests}

    def complete(self, exitstatus: int | None = None) -> bool:
        """True when the session ran every selected test and nobody interrupted it."""
        if self.interrupted or exitstatus == pytest.ExitCode.INTERRUPTED:
            return False
        return set(self.planned) <= self.completed_tests()

    def verdict(self, exitstatus: int | None = None) -> str:
        """The session's verdict (:func:`hil.qualification.verdict.session_verdict`)."""
        return session_verdict(setup_error=self.setup_error,
                               complete=self.complete(exitstatus), interrupted=self.interrupted,
                               exitstatus=exitstatus, invalid_bench=self.invalid_bench,
                               dut_failures=self.dut_failures, measurements=self.measurements,
                               tests=self.tests)

    def record(self, exitstatus: int | None = None) -> dict[str, Any]:
        """The qualification record of the session (schema ``agrihil.qualification/1``).

        Parameters
        ----------
        exitstatus : int, optional
            pytest's exit status, which decides whether the session was interrupted.

        Returns
        -------
        dict
            The record as written to ``record.json`` (see docs/reference/record-format.md).
        """
        runs, timing = self.run_cache.rows()
        return qualification_record(
            run_id=self.run_id, started_at=self.started_at,
            wall_s=time.perf_counter() - self.t0, verdict=self.verdict(exitstatus),
            profile=self.profile, bus=self.bus, clock=self.clock, seed=self.seed,
            suites=wanted_suites(self.suites), measurements=self.measurements,
            tests=self.tests, runs=runs, timing=timing,
            completeness=Completeness(self.complete(exitstatus), self.planned,
                                      self.completed_tests()),
            setup_error=self.setup_error, rig_overrides=self.rig_overrides,
            record_mode=self.record_mode)
