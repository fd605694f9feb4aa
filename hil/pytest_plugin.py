"""The agrihil pytest plugin: HIL suites as ordinary pytest files (after labgrid's plugin).

Registered through the ``pytest11`` entry point, so any ``pytest`` run has the options::

    --hil-dut PROFILE      DUT profile (TOML) to qualify; required by tests using HIL fixtures
    --hil-bus SPEC         softbus (default), virtual, inline, socketcan:vcan0, …
    --hil-clock MODE       lockstep (default) or realtime
    --hil-report DIR       where runs, record.json and report.html go (default: hil-report)
    --hil-seed N           base seed of every scenario run (default: each scenario's own)
    --hil-rig-override K=V rig config override (dotted key, TOML value), on top of the
                           profile's [rig]; repeatable (a campaign sample's dispersed rig)
    --hil-record MODE      full (default) or measurements: no bus logs, traces files or report.html
                           (a campaign's passing samples keep their measurements only)

Fixtures (scopes in brackets): ``hil_profile`` [session] the validated profile;
``hil_rig`` [session] the rig class the profile is wired to; ``hil_run`` [function] runs a
scenario against the DUT and returns its :class:`~hil.rig.RunResult` (runs are cached for the
session by scenario, seed and DUT, so suites can share them); ``hil_measure`` [function]
records a :class:`~hil.measurements.Measurement` with the profile's limits.

Markers, validated at collection: ``hil_rig(name)`` (the test is for that rig; it is skipped,
with the reason, when the DUT is wired to another) and ``hil_suite(name)`` (``fast``, ``full``,
``robustness``, ``busload``: real-time runs on a loaded bus, ~1 min each). A test passes
when its body passes *and* none of its measurements failed:
the plugin turns a failed measurement into a failed test, and a run with invalid bench timing
into a skipped test (the verdict ``invalid-bench``, never a DUT failure). At the end of the
session the qualification record (``record.json``, see docs/qualification-record.md) and the
HTML report are written to ``--hil-report``.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
import json
import math
import re
import time
import uuid
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from hil.dut.build import with_build_id
from hil.dut.factory import check_bus_for_dut, make_dut, profile_run_options
from hil.dut.physical import RESTART_SKIP_REASON, PhysicalDutSetupError
from hil.dut.profile import DutProfile, load_profile
from hil.errors import ConfigError, HilError
from hil.limits import MEASUREMENTS, applied_limit, known_measurement
from hil.measurements import Measurement, Outcome
from hil.qualification.console import REPORT_ERROR, QualificationConsole
from hil.qualification.verdict import session_verdict
from hil.record.atomic import write_json_atomic
from hil.record.recorder import versions
from hil.rig import Rig, RunOptions, RunResult, load_rig, run_scenario
from hil.rig.runner import CommandIdsError
from hil.rig.scenario import Scenario
from hil.validation import CLI_RANGES

SUITES = ("fast", "full", "robustness", "busload", "isobus")
#: the suite of ISOBUS implements ([wiring] isobus = true): field runs under the rig's Task
#: Controller; the other suites give the set-point by the rig's own frames
ISOBUS_SUITE = "isobus"
SCHEMA = "agrihil.qualification/1"


def pytest_addoption(parser: pytest.Parser) -> None:
    """Add the ``--hil-*`` options to pytest's command line (group "agrihil").

    Parameters
    ----------
    parser : pytest.Parser
        pytest's option parser.
    """
    group = parser.getgroup("agrihil", "agrihil hardware-in-the-loop")
    group.addoption("--hil-dut", metavar="PROFILE", help="DUT profile (TOML) under test")
    group.addoption("--hil-bus", metavar="SPEC", default="softbus",
                    help="bus spec (default: softbus, an embedded software bus)")
    group.addoption("--hil-clock", choices=["lockstep", "realtime"], default="lockstep",
                    help="clock of every run (default: lockstep)")
    group.addoption("--hil-report", metavar="DIR", default="hil-report",
                    help="directory for runs, record.json and report.html")
    group.addoption("--hil-seed", metavar="N", type=int, default=None,
                    help="base seed added to each scenario's seed (default: 0)")
    group.addoption("--hil-suite", metavar="NAMES", default="all",
                    help=f"comma-separated suites to run ({', '.join(SUITES)}, all); tests "
                         "without a hil_suite marker always run")
    group.addoption("--hil-build-id", metavar="ID", default=None,
                    help="build id of the DUT (a CI job's commit), instead of the profile's "
                         "[dut] build_id")
    group.addoption("--hil-rig-override", metavar="KEY=VALUE", action="append", default=[],
                    help="override a rig config parameter (dotted key, TOML value) for every "
                         "run, on top of the profile's [rig]; repeatable")
    group.addoption("--hil-record", choices=["full", "measurements"], default="full",
                    help="full (default): bus logs, traces and report.html; measurements: "
                         "no bus logs, no traces files, no report.html (campaign samples)")


@pytest.hookimpl(tryfirst=True)
def pytest_load_initial_conftests(early_config: pytest.Config, parser: pytest.Parser,
                                  args: list[str]) -> None:
    """A qualification (``--hil-dut``) runs no benchmarks: pytest-benchmark is blocked.

    Loaded, it creates an empty ``.benchmarks/`` in the working directory of every run.

    Parameters
    ----------
    early_config : pytest.Config
        pytest's configuration, before the plugins are configured.
    parser : pytest.Parser
        The option parser, unused.
    args : list of str
        The command line.
    """
    if any(a == "--hil-dut" or a.startswith("--hil-dut=") for a in args):
        early_config.pluginmanager.set_blocked("benchmark")


def pytest_configure(config: pytest.Config) -> None:
    """Register the markers and, with ``--hil-dut``, start the qualification session.

    The profile is loaded and validated, the bus checked against the DUT's kind and the seed
    range checked; the :class:`QualificationSession` is registered as a plugin so its hooks run.

    Parameters
    ----------
    config : pytest.Config
        pytest's configuration.

    Raises
    ------
    pytest.UsageError
        The profile, the bus spec or the seed is not usable (a one-line message naming the option).
    """
    config.addinivalue_line("markers", "hil_rig(name): a HIL test for the named rig")
    config.addinivalue_line("markers", f"hil_suite(name): suite of the test ({', '.join(SUITES)})")
    path = config.getoption("--hil-dut")
    if path:
        try:
            profile = with_build_id(load_profile(path), config.getoption("--hil-build-id"))
        except ConfigError as exc:
            raise pytest.UsageError(f"--hil-dut: {exc}") from exc
        try:   # a process DUT on an in-process bus would only time out, run after run
            check_bus_for_dut(config.getoption("--hil-bus"), profile.dut.kind,
                              inprocess_twin=bool(profile.launch.inprocess))
        except ConfigError as exc:
            raise pytest.UsageError(f"--hil-bus: {exc}") from exc
        seed = config.getoption("--hil-seed")
        seeds = CLI_RANGES["--seed"]   # the one table of valid ranges (hil.validation)
        if seed is not None and not seeds.contains(seed):   # a setup error, not the DUT's
            raise pytest.UsageError(f"--hil-seed: {seed} is not a seed: give an integer "
                                    f"{seeds.low} .. {seeds.high}")
        session = QualificationSession(
            profile=profile, bus=config.getoption("--hil-bus"),
            clock=config.getoption("--hil-clock"),
            report_dir=Path(config.getoption("--hil-report")),
            seed=config.getoption("--hil-seed"), suites=config.getoption("--hil-suite"),
            rig_overrides=_rig_overrides(profile, config.getoption("--hil-rig-override")),
            record_mode=config.getoption("--hil-record"))
        config.pluginmanager.register(session, "agrihil-qualification")
        config.pluginmanager.register(QualificationConsole(session, config), "agrihil-console")
        config.stash[_SESSION] = session


_SESSION = pytest.StashKey["QualificationSession"]()


def _rig_overrides(profile: DutProfile, items: list[str]) -> dict[str, Any]:
    """``KEY=VALUE`` options as a nested override table, checked by the rig's loader."""
    if not items:
        return {}
    from hil.campaign.overrides import parse_overrides

    try:
        return parse_overrides(items, rig=profile.dut.rig, base=profile.rig_config)
    except ConfigError as exc:
        raise pytest.UsageError(f"--hil-rig-override: {exc}") from exc


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Validate the ``hil_rig`` and ``hil_suite`` markers and select the tests to run.

    Tests of suites not named by ``--hil-suite`` are deselected; with a DUT, tests marked for
    another rig than the DUT's are skipped with the reason.

    Parameters
    ----------
    config : pytest.Config
        pytest's configuration.
    items : list of pytest.Item
        The collected tests; deselected ones are removed in place.

    Raises
    ------
    pytest.UsageError
        A marker names no known rig or suite, or ``--hil-suite`` names an unknown suite.
    """
    from hil.rig.registry import available_rigs

    session = config.stash.get(_SESSION, None)
    wanted = _wanted_suites(config.getoption("--hil-suite"))
    deselected = []
    for item in items:
        for mark in item.iter_markers("hil_rig"):
            if len(mark.args) != 1 or str(mark.args[0]).replace("-", "_") not in available_rigs():
                raise pytest.UsageError(f"{item.nodeid}: hil_rig marker needs one rig name "
                                        f"({', '.join(available_rigs())}), got {mark.args!r}")
        for mark in item.iter_markers("hil_suite"):
            if len(mark.args) != 1 or mark.args[0] not in SUITES:
                raise pytest.UsageError(f"{item.nodeid}: hil_suite marker needs one of "
                                        f"{', '.join(SUITES)}, got {mark.args!r}")
        suite_mark = item.get_closest_marker("hil_suite")
        if suite_mark is not None and suite_mark.args[0] not in wanted:
            deselected.append(item)
            continue
        rig_mark = item.get_closest_marker("hil_rig")
        if session is not None and rig_mark is not None:
            want = str(rig_mark.args[0]).replace("-", "_")
            have = session.profile.dut.rig.replace("-", "_")
            if want != have:
                item.add_marker(pytest.mark.skip(
                    reason=f"a {want} suite; the DUT {session.profile.name} drives the {have} rig"))
            elif suite_mark is not None:
                why = _interface_mismatch(suite_mark.args[0], session.profile)
                if why:
                    item.add_marker(pytest.mark.skip(reason=why))
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = [item for item in items if item not in deselected]


def _interface_mismatch(suite: str, profile: DutProfile) -> str:
    """Why a rig test of ``suite`` cannot judge the DUT of ``profile`` ("" if it can)."""
    if profile.wiring.isobus and suite != ISOBUS_SUITE:
        return (f"a {suite} test gives the set-point by the rig's own frames; the DUT "
                f"{profile.name} is an ISOBUS implement (its suite: {ISOBUS_SUITE})")
    if suite == ISOBUS_SUITE and not profile.wiring.isobus:
        return (f"an {ISOBUS_SUITE} test (a field run under the rig's Task Controller); the "
                f"DUT {profile.name} is not an ISOBUS implement ([wiring] isobus = false)")
    return ""


def _wanted_suites(option: str) -> set[str]:
    names = {n.strip() for n in option.split(",") if n.strip()}
    if "all" in names:
        return set(SUITES)
    unknown = names - set(SUITES)
    if unknown or not names:
        raise pytest.UsageError(f"--hil-suite: unknown suite {', '.join(sorted(unknown))!s}; "
                                f"choose from {', '.join(SUITES)}, all")
    return names


@dataclass
class _RunEntry:
    result: RunResult
    rel_dir: str
    scenario: str


@dataclass
class QualificationSession:
    """Everything one qualification collects; written out at the end of the session."""

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
    measurements: list[dict[str, Any]] = field(default_factory=list)
    tests: list[dict[str, Any]] = field(default_factory=list)
    runs: dict[tuple[Any, ...], _RunEntry] = field(default_factory=dict)
    by_item: dict[str, list[Measurement]] = field(default_factory=dict)
    invalid_bench: dict[str, str] = field(default_factory=dict)
    #: node ids of the tests selected to run (set when collection finishes)
    planned: list[str] = field(default_factory=list)
    #: a SIGINT/SIGTERM (KeyboardInterrupt) ended the session early
    interrupted: bool = False
    #: runs each test used (node id -> results), to judge what the test's code raised
    runs_of_test: dict[str, list[RunResult]] = field(default_factory=dict)
    #: tests failed because their DUT stopped (node id -> "the DUT stopped at t = … s")
    dut_failures: dict[str, str] = field(default_factory=dict)
    #: a setup problem that ends the session (a physical ECU that is not on the bus)
    setup_error: str = ""

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
        key = (rig_cls, repr(scenario), seed_used, profile.name, profile.sha256, bus,
               clock)
        cached = self.runs.get(key)
        if cached is not None:
            self.runs_of_test.setdefault(nodeid, []).append(cached.result)
            return cached.result
        if profile.dut.kind == "physical" and any(e.dut == "restart" for e in scenario.events):
            pytest.skip(RESTART_SKIP_REASON.format(scenario=scenario.name))
        rel = f"runs/{_slug(nodeid)}{'-' + _slug(label) if label else ''}"
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
        except (PhysicalDutSetupError, CommandIdsError) as exc:
            # not a verdict on the ECU: the qualification stops as a setup error (exit 2)
            self.setup_error = str(exc)
            pytest.exit(f"setup error: {exc}", returncode=2)
        self.runs[key] = _RunEntry(result, rel, scenario.name)
        # bus conformance of the DUT under qualification, from the run's bus log (a
        # measurements-only campaign sample keeps none: its full reruns carry conformance)
        if profile is self.profile and self.record_mode == "full":
            self._conformance(nodeid, rig_cls, result)
        self.runs_of_test.setdefault(nodeid, []).append(result)
        timing = result.record.get("timing") or {}
        if timing.get("mode") == "realtime" and not timing.get("valid", True):
            self.invalid_bench[nodeid] = rel
        return result

    def _conformance(self, nodeid: str, rig_cls: type[Rig], result: RunResult) -> None:
        """Judge the run's bus conformance (:mod:`hil.conformance`).

        Its measurements are the test's, its per-message table goes to the run's
        ``conformance.json``.
        """
        from hil.conformance import run_conformance, write_detail

        # the run's directory tells its measurements from the other runs' (same names)
        run = self.run_dir_of(result).removeprefix("runs/")
        found = run_conformance(result.record, result.out_dir, self.profile,
                                physics_period_s=rig_cls.physics_period_s,
                                conditions={"run": run})
        write_detail(found, result.out_dir)
        stopped = _stopped_reason(result) if result.record.get("error") else ""
        for m in found.measurements:
            if stopped:   # what a dead DUT left on the bus judges nothing: failed, with why
                m = dataclasses.replace(m, value=math.nan,
                                        note=stopped + (f"; {m.note}" if m.note else ""))
            self._keep(nodeid, m, result)

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
        for entry in self.runs.values():
            if entry.result is result:
                return entry.rel_dir
        return ""

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
        rig = self.profile.dut.rig.replace("-", "_")
        if not known_measurement(name, rig):
            raise ConfigError(f"{nodeid}: measurement {name!r} is not in the catalogue "
                              f"(hil/limits.py) for the {rig} rig")
        if run is not None and run.record.get("error"):
            value = math.nan
            note = _stopped_reason(run) + (f"; {note}" if note else "")
        conditions = dict(conditions or {})
        limit = applied_limit(name, conditions, self.profile.limit(name))
        if limit.problem:   # a limit stated for conditions this measurement cannot have
            where = f"{self.profile.path}: " if limit.source == "profile" else ""
            measured = (f"; measured {float(value):g} {MEASUREMENTS[name].unit}"
                        if math.isfinite(float(value)) else "")
            note = f"limit not applied: {where}{limit.problem}{measured}" + (
                f"; {note}" if note else "")
            value = math.nan
        m = Measurement(name, float(value), MEASUREMENTS[name].unit, low=limit.low,
                        high=limit.high, conditions=conditions, note=note,
                        limit_source=limit.source,
                        **({"marginal_band": limit.marginal}
                           if limit.marginal is not None else {}))
        return self._keep(nodeid, m, run)

    def _keep(self, nodeid: str, m: Measurement, run: RunResult | None) -> Measurement:
        entry = m.to_dict()
        entry["test"] = nodeid
        entry["run"] = self.run_dir_of(run) if run is not None else ""
        self.measurements.append(entry)
        self.by_item.setdefault(nodeid, []).append(m)
        return m

    def dead_dut_reason(self, nodeid: str) -> str | None:
        """Why a test's runs say nothing about its measurements (its DUT stopped), or None."""
        for result in self.runs_of_test.get(nodeid, ()):
            if result.record.get("error"):
                return _stopped_reason(result)
        return None

    # --- pytest hooks ---------------------------------------------------------------------------
    @pytest.hookimpl(wrapper=True)
    def pytest_pyfunc_call(self, pyfuncitem: pytest.Function) -> Generator[None, Any, Any]:
        """Fail a test whose DUT stopped with that reason, not with what its code raised.

        What the test's code raised computing on the short traces is not a suite error (and is
        not shown).
        """
        try:
            return (yield)
        except Exception as exc:
            reason = self.dead_dut_reason(pyfuncitem.nodeid)
            if reason is None:
                raise
            self.dut_failures[pyfuncitem.nodeid] = reason
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
        import inspect

        rig = self.profile.dut.rig.replace("-", "_")
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
        done = {m.name for m in self.by_item.get(item.nodeid, [])}
        dead = next((r for r in self.runs_of_test.get(item.nodeid, ())
                     if r.record.get("error")), None)
        failed = []
        for name in names:
            if name not in done:
                self.measure(item.nodeid, name, math.nan, conditions=conditions, run=dead)
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
        measured = self.by_item.get(item.nodeid, [])
        for m in measured:    # junit.xml <property> elements (junitxml reads them at teardown)
            item.user_properties.append((f"{m.name}{_conditions(m.conditions)}",
                                         f"{m.value:g} {m.unit} ({m.outcome.value})"))
        if item.nodeid in self.invalid_bench and report.outcome != "skipped":
            report.outcome = "skipped"
            report.longrepr = (str(item.path), item.location[1] or 0,
                               "invalid bench: the rig's real-time timing was out of bounds "
                               f"({self.invalid_bench[item.nodeid]}); says nothing about the DUT")
            return
        bad = [m for m in measured if m.outcome in (Outcome.FAIL, Outcome.ERROR)]
        if bad and report.outcome == "passed":
            report.outcome = "failed"
            lines = [f"{m.name}{_conditions(m.conditions)} = {m.value:g} {m.unit}: "
                     f"{m.outcome.value} (limits {m.low} .. {m.high})"
                     + (f" - {m.note}" if m.note else "") for m in bad]
            report.longrepr = "measurements out of limits:\n  " + "\n  ".join(lines)

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        """Log the test's outcome for the record.

        The console prints it (:mod:`hil.qualification.console`).

        Parameters
        ----------
        report : pytest.TestReport
            The report of one phase of a test.
        """
        self._log_test(report)

    def _log_test(self, report: pytest.TestReport) -> None:
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
        record = self.record(exitstatus)
        self.report_dir.mkdir(parents=True, exist_ok=True)
        # atomic: a second Ctrl-C or a kill while writing leaves the old file or the new one
        write_json_atomic(self.report_dir / "record.json", record)
        if self.record_mode == "measurements":
            return
        from hil.report import write_html

        try:
            write_html(self.report_dir)
        except Exception as exc:  # the record is written; say loudly the page is not
            session.config.stash[REPORT_ERROR] = f"report.html not written: {exc}"

    # --- the record ----------------------------------------------------------------------------
    def completed_tests(self) -> set[str]:
        """Node ids of the tests that ran to their end (passed, failed or skipped)."""
        return {t["nodeid"] for t in self.tests}

    def complete(self, exitstatus: int | None = None) -> bool:
        """True when the session ran every selected test and nobody interrupted it."""
        if self.interrupted or exitstatus == pytest.ExitCode.INTERRUPTED:
            return False
        return set(self.planned) <= self.completed_tests()

    @property
    def name(self) -> str:
        """The name of the DUT under qualification."""
        return self.profile.name

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
        worst: dict[str, Any] | None = None
        runs = []
        for entry in self.runs.values():
            rec = entry.result.record
            timing = rec.get("timing") or None
            if timing and (worst is None or timing.get("lateness_p99_s", 0) >
                           worst.get("lateness_p99_s", 0)):
                worst = timing
            runs.append({"dir": entry.rel_dir, "scenario": entry.scenario,
                         "verdict": rec.get("verdict"), "error": rec.get("error"),
                         "sim_s": round(entry.result.sim_s, 3),
                         "wall_s": round(entry.result.wall_s, 3)})
        rig_cls = load_rig(self.profile.dut.rig)
        return {
            "schema": SCHEMA,
            "run_id": self.run_id,
            "started_at": self.started_at,
            "wall_s": round(time.perf_counter() - self.t0, 3),
            "verdict": self.verdict(exitstatus),
            "dut": {**self.profile.identity(), "parameters": self.profile.parameters},
            "rig": {"name": rig_cls.name, **_rig_config_identity(rig_cls, self.profile)},
            "bus": self.bus, "clock": self.clock, "seed": self.seed,
            "suites": sorted(_wanted_suites(self.suites)),
            "versions": versions(),
            "limits": {name: {"low": lim.low, "high": lim.high,
                              "unit": MEASUREMENTS[name].unit,
                              **({"when": [c.to_dict() for c in lim.cases]} if lim.cases
                                 else {})}
                       for name, lim in self.profile.limits.items()},
            "measurements": self.measurements,
            "tests": self.tests,
            "runs": runs,
            "timing": worst,
            # only in a record of a qualification that did not run all its tests
            **({} if self.complete(exitstatus) else {
                "complete": False, "tests_planned": len(self.planned),
                "tests_completed": len(self.completed_tests() & set(self.planned)),
                "tests_not_run": [n for n in self.planned if n not in self.completed_tests()],
            }),
            **({"error": self.setup_error} if self.setup_error else {}),
            **({"rig_overrides": _dotted(self.rig_overrides)} if self.rig_overrides else {}),
            **({"record_mode": self.record_mode} if self.record_mode != "full" else {}),
        }




def _rig_config_identity(rig_cls: type[Rig], profile: DutProfile) -> dict[str, Any]:
    """What the record says of the rig's config.

    Its hash (the packaged config with the profile's ``[rig]`` overrides applied) and the
    overrides as dotted keys.
    """
    config = rig_cls.load_config(profile.rig_config, source=str(profile.path or ""))
    out: dict[str, Any] = {}
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        text = json.dumps(dataclasses.asdict(config), sort_keys=True, default=str)
        out["config_sha256"] = hashlib.sha256(text.encode()).hexdigest()
    out["config_overrides"] = _dotted(profile.rig_config) or "none (the packaged config)"
    return out


def _dotted(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in table.items():
        if isinstance(value, dict):
            out.update(_dotted(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def _stopped_reason(run: RunResult) -> str:
    """"the DUT stopped at t = 3.0 s (exited with SIGSEGV)" for a run the DUT ended."""
    stopped = run.record.get("dut_stopped")
    if isinstance(stopped, dict) and "t_s" in stopped:
        return f"the DUT stopped at t = {stopped['t_s']:.1f} s ({stopped.get('what', '?')})"
    return f"the run ended early: {run.record.get('error')}"


def _slug(text: str) -> str:
    text = text.split("::", 1)[-1] if "::" in text else text
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-")[:80]


def _conditions(conditions: dict[str, Any]) -> str:
    if not conditions:
        return ""
    return "[" + ", ".join(f"{k}={v}" for k, v in sorted(conditions.items())) + "]"


# --- fixtures ----------------------------------------------------------------------------------
@pytest.fixture(scope="session")
def hil_session(request: pytest.FixtureRequest) -> QualificationSession:
    """The qualification session of this pytest run [session scope].

    Raises
    ------
    pytest.UsageError
        No ``--hil-dut`` was given.
    """
    session = request.config.stash.get(_SESSION, None)
    if session is None:
        raise pytest.UsageError("HIL suites need a DUT: pytest --hil-dut PROFILE "
                                "(or run them with `hil qualify PROFILE`)")
    return session


@pytest.fixture(scope="session")
def hil_profile(hil_session: QualificationSession) -> DutProfile:
    """The DUT profile under qualification, validated [session scope].

    Returns
    -------
    DutProfile
        The profile given by ``--hil-dut`` (with ``--hil-build-id`` applied).
    """
    return hil_session.profile


@pytest.fixture(scope="session")
def hil_rig(hil_session: QualificationSession) -> type[Rig]:
    """The rig class the DUT profile is wired to [session scope].

    Returns
    -------
    type of Rig
        The class named by the profile's ``[dut] rig``.
    """
    return load_rig(hil_session.profile.dut.rig)


@pytest.fixture
def hil_run(request: pytest.FixtureRequest, hil_session: QualificationSession,
            hil_rig: type[Rig]) -> Callable[..., RunResult]:
    """A function that runs a scenario against the DUT and returns its result [function scope].

    The function is ``run(scenario, *, label="", rig=None, **kw)``: ``scenario`` is a
    :class:`~hil.rig.scenario.Scenario` or the name of one of the rig's packaged scenarios,
    ``label`` tells apart runs of one test (it names the run's directory), ``rig`` overrides the
    DUT's rig class, and ``kw`` goes to :meth:`QualificationSession.run` (``seed``, ``profile``,
    ``bus``, ``clock``, ``step_timeout_s``). Runs are cached for the session by scenario, seed, DUT,
    bus and clock. A run whose setup fails fails the test with the reason.

    Returns
    -------
    callable
        ``run(scenario, *, label="", rig=None, **kw) -> RunResult``.
    """
    nodeid = request.node.nodeid

    def run(scenario: Scenario | str, *, label: str = "", rig: type[Rig] | None = None,
            **kw: Any) -> RunResult:
        try:
            return hil_session.run(nodeid, rig or hil_rig, scenario, label=label, **kw)
        except HilError as exc:
            pytest.fail(f"setup of the run failed: {exc}", pytrace=False)
    return run


@pytest.fixture
def hil_measure(request: pytest.FixtureRequest,
                hil_session: QualificationSession) -> Callable[..., Measurement]:
    """A function that records a measurement with the profile's limits [function scope].

    The function is ``measure(name, value, **kw)``; see :meth:`QualificationSession.measure` for
    the keywords (``conditions``, ``run``, ``note``). A failed measurement fails the test.

    Returns
    -------
    callable
        ``measure(name, value, **kw) -> Measurement``.
    """
    nodeid = request.node.nodeid

    def measure(name: str, value: float, **kw: Any) -> Measurement:
        return hil_session.measure(nodeid, name, value, **kw)
    return measure
