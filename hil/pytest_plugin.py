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

This module is the plugin's face to pytest: its options, markers, fixtures and the
module-level hooks that read them. The session it starts, and what that session does with the
runs and measurements, is :mod:`hil.qualification` (one module per idea: ``session``,
``runs``, ``conformance_runs``, ``measurements``, ``outcomes``, ``summary``, ``record``,
``verdict``, ``console``, ``suites``).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hil.dut.build import with_build_id
from hil.dut.factory import check_bus_for_dut
from hil.dut.profile import DutProfile, load_profile
from hil.errors import ConfigError, HilError
from hil.measurements import Measurement
from hil.qualification.console import QualificationConsole
from hil.qualification.outcomes import TestOutcomes
from hil.qualification.record import SCHEMA, rig_config_identity  # noqa: F401 (re-exported)
from hil.qualification.session import QualificationSession
from hil.qualification.suites import (  # noqa: F401 (ISOBUS_SUITE re-exported)
    ISOBUS_SUITE,
    SUITES,
    interface_mismatch,
    wanted_suites,
)
from hil.rig import Rig, RunResult, load_rig
from hil.rig.scenario import Scenario
from hil.validation import CLI_RANGES

#: the names these had when they lived here (QualificationSession, SUITES, ISOBUS_SUITE and
#: SCHEMA are imported from here too)
_rig_config_identity = rig_config_identity
_interface_mismatch = interface_mismatch


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
        config.pluginmanager.register(TestOutcomes(session), "agrihil-outcomes")
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
                why = interface_mismatch(suite_mark.args[0], session.profile)
                if why:
                    item.add_marker(pytest.mark.skip(reason=why))
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = [item for item in items if item not in deselected]


def _wanted_suites(option: str) -> set[str]:
    """The suites ``--hil-suite`` selects; an unknown one is a usage error."""
    try:
        return wanted_suites(option)
    except ConfigError as exc:
        raise pytest.UsageError(f"--hil-suite: {exc}") from exc


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
