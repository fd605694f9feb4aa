"""The scenario runs of a qualification: cached by what makes a run the same, named by the
test that asked first, and listed in the record.

A run is the same run when its rig, scenario, seed, DUT (name and profile hash), bus and clock
are: a second test asking for it gets the first one's result (suites share runs). This module
keeps them and answers what the session asks of them (their directory, whether a test's DUT
stopped, the record's ``runs`` rows and worst timing); starting a run is
:meth:`hil.qualification.session.QualificationSession.run`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

from hil.dut.profile import DutProfile
from hil.rig import Rig, RunResult
from hil.rig.scenario import Scenario

#: what makes two runs the same run (see :func:`run_key`)
RunKey = tuple[Any, ...]


@dataclass
class RunEntry:
    """One run of the session: its result, its directory under the report and its scenario."""

    result: RunResult
    rel_dir: str
    scenario: str


def run_key(rig_cls: type[Rig], scenario: Scenario, seed: int, profile: DutProfile, bus: str,
            clock: str) -> RunKey:
    """The key runs are cached by: rig, scenario, seed, DUT (name and hash), bus and clock."""
    return (rig_cls, repr(scenario), seed, profile.name, profile.sha256, bus, clock)


def run_dir(nodeid: str, label: str = "") -> str:
    """The report-relative directory of a run: ``runs/<test>[-<label>]``."""
    return f"runs/{slug(nodeid)}{'-' + slug(label) if label else ''}"


def slug(text: str) -> str:
    """A test's node id (its part after the file) or a label as a directory name."""
    text = text.split("::", 1)[-1] if "::" in text else text
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-")[:80]


def stopped_reason(run: RunResult) -> str:
    """"the DUT stopped at t = 3.0 s (exited with SIGSEGV)" for a run the DUT ended."""
    stopped = run.record.get("dut_stopped")
    if isinstance(stopped, dict) and "t_s" in stopped:
        return f"the DUT stopped at t = {stopped['t_s']:.1f} s ({stopped.get('what', '?')})"
    return f"the run ended early: {run.record.get('error')}"


@dataclass
class RunCache:
    """The runs of a session by key, and the runs each test used."""

    entries: dict[RunKey, RunEntry] = field(default_factory=dict)
    #: runs each test used (node id -> results), to judge what the test's code raised
    of_test: dict[str, list[RunResult]] = field(default_factory=dict)

    def get(self, key: RunKey, nodeid: str) -> RunResult | None:
        """The cached run of ``key`` (now also used by ``nodeid``), or None."""
        cached = self.entries.get(key)
        if cached is None:
            return None
        self.of_test.setdefault(nodeid, []).append(cached.result)
        return cached.result

    def add(self, key: RunKey, entry: RunEntry) -> None:
        """Keep a new run under ``key``."""
        self.entries[key] = entry

    def used(self, nodeid: str, result: RunResult) -> None:
        """Note that the test ``nodeid`` used ``result``."""
        self.of_test.setdefault(nodeid, []).append(result)

    def dir_of(self, result: RunResult) -> str:
        """The report-relative directory of ``result`` ("" if it is no run of this cache)."""
        for entry in self.entries.values():
            if entry.result is result:
                return entry.rel_dir
        return ""

    def dead_dut_reason(self, nodeid: str) -> str | None:
        """Why a test's runs say nothing about its measurements (its DUT stopped), or None."""
        for result in self.of_test.get(nodeid, ()):
            if result.record.get("error"):
                return stopped_reason(result)
        return None

    def first_dead(self, nodeid: str) -> RunResult | None:
        """The first run of the test ``nodeid`` that its DUT ended, or None."""
        return next((r for r in self.of_test.get(nodeid, ()) if r.record.get("error")), None)

    def rows(self) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
        """The record's ``runs`` rows and ``timing`` (the run with the worst p99 lateness)."""
        worst: dict[str, Any] | None = None
        rows = []
        for entry in self.entries.values():
            rec = entry.result.record
            timing = rec.get("timing") or None
            if timing and (worst is None or timing.get("lateness_p99_s", 0) >
                           worst.get("lateness_p99_s", 0)):
                worst = timing
            rows.append({"dir": entry.rel_dir, "scenario": entry.scenario,
                         "verdict": rec.get("verdict"), "error": rec.get("error"),
                         "sim_s": round(entry.result.sim_s, 3),
                         "wall_s": round(entry.result.wall_s, 3)})
        return rows, worst
