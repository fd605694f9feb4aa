"""The agrihil pytest plugin: HIL suites as ordinary pytest files (after labgrid's plugin).

Registered through the ``pytest11`` entry point, so any ``pytest`` run has the options::

    --hil-dut PROFILE      DUT profile (TOML) to qualify; required by tests using HIL fixtures
    --hil-bus SPEC         softbus (default), virtual, inline, socketcan:vcan0, …
    --hil-clock MODE       lockstep (default) or realtime
    --hil-report DIR       where runs, record.json and report.html go (default: hil-report)
    --hil-seed N           base seed of every scenario run (default: each scenario's own)
    --hil-rig-override K=V rig config override (dotted key, TOML value), on top of the
                           profile's [rig]; repeatable (a campaign sample's dispersed rig)
    --hil-record MODE      full (default) or measurements: no bus logs and no report.html
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

from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import DutProfile, load_profile
from hil.errors import ConfigError, HilError
from hil.limits import MEASUREMENTS, known_measurement
from hil.measurements import Measurement, Outcome
from hil.record.recorder import versions
from hil.rig import Rig, RunOptions, RunResult, load_rig, run_scenario
from hil.rig.scenario import Scenario

SUITES = ("fast", "full", "robustness", "busload")
SCHEMA = "agrihil.qualification/1"


def pytest_addoption(parser: pytest.Parser) -> None:
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
    group.addoption("--hil-rig-override", metavar="KEY=VALUE", action="append", default=[],
                    help="override a rig config parameter (dotted key, TOML value) for every "
                         "run, on top of the profile's [rig]; repeatable")
    group.addoption("--hil-record", choices=["full", "measurements"], default="full",
                    help="full (default): bus logs, traces and report.html; measurements: "
                         "no bus logs, no report.html (campaign samples)")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "hil_rig(name): a HIL test for the named rig")
    config.addinivalue_line("markers", f"hil_suite(name): suite of the test ({', '.join(SUITES)})")
    path = config.getoption("--hil-dut")
    if path:
        try:
            profile = load_profile(path)
        except ConfigError as exc:
            raise pytest.UsageError(f"--hil-dut: {exc}") from exc
        session = QualificationSession(
            profile=profile, bus=config.getoption("--hil-bus"),
            clock=config.getoption("--hil-clock"),
            report_dir=Path(config.getoption("--hil-report")),
            seed=config.getoption("--hil-seed"), suites=config.getoption("--hil-suite"),
            rig_overrides=_rig_overrides(profile, config.getoption("--hil-rig-override")),
            record_mode=config.getoption("--hil-record"))
        config.pluginmanager.register(session, "agrihil-qualification")
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
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = [item for item in items if item not in deselected]


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

    # --- runs ---------------------------------------------------------------------------------
    def run(self, nodeid: str, rig_cls: type[Rig], scenario: Scenario | str, *,
            label: str = "", seed: int | None = None, profile: DutProfile | None = None,
            bus: str | None = None, clock: str | None = None,
            step_timeout_s: float = 5.0) -> RunResult:
        """One scenario run of ``profile`` (default: the DUT under qualification), cached.
        ``bus``/``clock`` override the session's (a suite that only means something in real
        time, such as bus load, runs real time even in a lockstep qualification)."""
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
            return cached.result
        rel = f"runs/{_slug(nodeid)}{'-' + _slug(label) if label else ''}"
        out_dir = self.report_dir / rel
        dut, build = make_dut(profile, bus=bus, clock=clock, log_dir=out_dir)
        # the rig is wired as the DUT under qualification says (a baseline run too)
        wiring = profile_run_options(profile, rig_from=self.profile)
        if self.rig_overrides:
            from hil.config import merge_tables

            wiring["rig_config"] = merge_tables(wiring["rig_config"], self.rig_overrides)
        result = run_scenario(rig_cls, scenario, dut, RunOptions(
            out_dir=out_dir, clock=clock, bus=bus, seed=seed_used,
            step_timeout_s=step_timeout_s, record_bus=self.record_mode == "full",
            **wiring,
            extra_meta={"dut_identity": profile.identity(), "dut_build": build,
                        "test": nodeid}))
        self.runs[key] = _RunEntry(result, rel, scenario.name)
        timing = result.record.get("timing") or {}
        if timing.get("mode") == "realtime" and not timing.get("valid", True):
            self.invalid_bench[nodeid] = rel
        return result

    def run_dir_of(self, result: RunResult) -> str:
        for entry in self.runs.values():
            if entry.result is result:
                return entry.rel_dir
        return ""

    # --- measurements ---------------------------------------------------------------------------
    def measure(self, nodeid: str, name: str, value: float, *,
                conditions: dict[str, Any] | None = None, run: RunResult | None = None,
                note: str = "") -> Measurement:
        rig = self.profile.dut.rig.replace("-", "_")
        if not known_measurement(name, rig):
            raise ConfigError(f"{nodeid}: measurement {name!r} is not in the catalogue "
                              f"(hil/limits.py) for the {rig} rig")
        if run is not None and run.record.get("error"):
            value = math.nan
            note = (note + "; " if note else "") + f"run ended early: {run.record['error']}"
        limit = self.profile.limit(name)
        m = Measurement(name, float(value), MEASUREMENTS[name].unit,
                        low=limit.low if limit else None, high=limit.high if limit else None,
                        conditions=dict(conditions or {}), note=note,
                        **({"marginal_band": limit.marginal}
                           if limit is not None and limit.marginal is not None else {}))
        entry = m.to_dict()
        entry["test"] = nodeid
        entry["run"] = self.run_dir_of(run) if run is not None else ""
        self.measurements.append(entry)
        self.by_item.setdefault(nodeid, []).append(m)
        return m

    # --- pytest hooks ---------------------------------------------------------------------------
    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_makereport(self, item: pytest.Item,
                                  call: pytest.CallInfo[None]) -> Generator[None, Any, None]:
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
        if report.when == "call" or (report.when == "setup" and report.outcome != "passed"):
            message = ""
            if report.outcome != "passed" and report.longrepr is not None:
                message = (report.longrepr[2] if isinstance(report.longrepr, tuple)
                           else str(report.longrepr))[-2000:]
            self.tests.append({"nodeid": report.nodeid, "outcome": report.outcome,
                               "duration_s": round(report.duration, 3), "message": message})

    def pytest_sessionfinish(self, session: pytest.Session, exitstatus: int) -> None:
        record = self.record(exitstatus)
        self.report_dir.mkdir(parents=True, exist_ok=True)
        (self.report_dir / "record.json").write_text(json.dumps(record, indent=2, default=str))
        if self.record_mode == "measurements":
            return
        from hil.report import write_html

        try:
            write_html(self.report_dir)
        except Exception as exc:  # the record is written; say loudly the page is not
            session.config.stash[_REPORT_ERROR] = f"report.html not written: {exc}"

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        error = terminalreporter.config.stash.get(_REPORT_ERROR, None)
        verdict = self._verdict()
        terminalreporter.write_sep("=", f"agrihil qualification of {self.profile.name}: "
                                        f"{verdict.upper()}")
        counts: dict[str, int] = {}
        for m in self.measurements:
            counts[m["outcome"]] = counts.get(m["outcome"], 0) + 1
        terminalreporter.write_line(
            f"measurements: {', '.join(f'{v} {k}' for k, v in sorted(counts.items())) or 'none'}"
            f"; record: {self.report_dir / 'record.json'}")
        if error:
            terminalreporter.write_line(f"agrihil: ERROR: {error}", red=True)

    # --- the record ----------------------------------------------------------------------------
    def _verdict(self, exitstatus: int | None = None) -> str:
        if self.invalid_bench:
            return "invalid-bench"
        if exitstatus in (pytest.ExitCode.INTERRUPTED, pytest.ExitCode.INTERNAL_ERROR,
                          pytest.ExitCode.USAGE_ERROR) or not self.measurements:
            return "error"
        if any(m["outcome"] in ("fail", "error") for m in self.measurements):
            return "fail"
        if any(t["outcome"] == "failed" for t in self.tests):
            return "fail"
        return "pass"

    def record(self, exitstatus: int | None = None) -> dict[str, Any]:
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
            "verdict": self._verdict(exitstatus),
            "dut": {**self.profile.identity(), "parameters": self.profile.parameters},
            "rig": {"name": rig_cls.name, **_rig_config_identity(rig_cls, self.profile)},
            "bus": self.bus, "clock": self.clock, "seed": self.seed,
            "suites": sorted(_wanted_suites(self.suites)),
            "versions": versions(),
            "limits": {name: {"low": lim.low, "high": lim.high,
                              "unit": MEASUREMENTS[name].unit}
                       for name, lim in self.profile.limits.items()},
            "measurements": self.measurements,
            "tests": self.tests,
            "runs": runs,
            "timing": worst,
            **({"rig_overrides": _dotted(self.rig_overrides)} if self.rig_overrides else {}),
            **({"record_mode": self.record_mode} if self.record_mode != "full" else {}),
        }


_REPORT_ERROR = pytest.StashKey[str]()


def _rig_config_identity(rig_cls: type[Rig], profile: DutProfile) -> dict[str, Any]:
    """What the record says of the rig's config: its hash (the packaged config with the
    profile's ``[rig]`` overrides applied) and the overrides as dotted keys."""
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
    session = request.config.stash.get(_SESSION, None)
    if session is None:
        raise pytest.UsageError("HIL suites need a DUT: pytest --hil-dut PROFILE "
                                "(or run them with `hil qualify PROFILE`)")
    return session


@pytest.fixture(scope="session")
def hil_profile(hil_session: QualificationSession) -> DutProfile:
    return hil_session.profile


@pytest.fixture(scope="session")
def hil_rig(hil_session: QualificationSession) -> type[Rig]:
    return load_rig(hil_session.profile.dut.rig)


@pytest.fixture
def hil_run(request: pytest.FixtureRequest, hil_session: QualificationSession,
            hil_rig: type[Rig]) -> Callable[..., RunResult]:
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
    nodeid = request.node.nodeid

    def measure(name: str, value: float, **kw: Any) -> Measurement:
        return hil_session.measure(nodeid, name, value, **kw)
    return measure
