"""One scenario run of a qualification, read from its directory without ever raising.

What cannot be read (a missing ``traces.npz``, a broken ``record.json``, a rig nobody knows)
becomes a note the page shows where the plot would have been.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from hil.record.traces import load_traces
from hil.report.markup import relative_href
from hil.report.record import MeasurementRow, QualRecord, RunRef

#: the artifacts listed first in the runs table, in this order
KNOWN_ARTIFACTS = ("record.json", "bus.log", "bus.asc", "bus-unheard.log", "bus.blf",
                   "traces.npz", "traces.csv", "truth.npz", "stdout.log", "stderr.log", "plot.png")


@dataclass
class RunData:
    ref: RunRef
    path: Path
    rig: str
    record: dict[str, Any] = field(default_factory=dict)
    traces: dict[str, np.ndarray] | None = None
    units: dict[str, str] = field(default_factory=dict)
    truth: dict[str, np.ndarray] | None = None
    plot_groups: list[tuple[str, list[str]]] = field(default_factory=list)
    measurements: list[MeasurementRow] = field(default_factory=list)
    artifacts: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def anchor(self) -> str:
        return "run-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in self.ref.dir)

    @property
    def scenario(self) -> str:
        return self.ref.scenario or str(self.record.get("scenario") or "")

    @property
    def verdict(self) -> str:
        return self.ref.verdict or str(self.record.get("verdict") or "")

    @property
    def error(self) -> str:
        return str(self.record.get("error") or self.ref.error or "")

    @property
    def result(self) -> str:
        """What the page shows for the run: its own verdict when it did not complete (error,
        aborted, invalid bench) or nothing judged it, else the worst of its measurements (a
        run under a suite records ``no-measurements``: the suite measures, not the run)."""
        if self.verdict in ("error", "aborted", "invalid-bench") or not self.measurements:
            return self.verdict
        statuses = {m.status for m in self.measurements}
        if statuses & {"fail", "error"}:
            return "fail"
        return "pass" if statuses & {"pass", "marginal"} else "info"

    @property
    def events(self) -> list[dict[str, Any]]:
        events = self.record.get("events")
        return [e for e in events if isinstance(e, dict)] if isinstance(events, list) else []

    @property
    def timing(self) -> dict[str, Any]:
        timing = self.record.get("timing")
        return timing if isinstance(timing, dict) else {}


@cache
def rig_plot_groups(rig: str) -> tuple[tuple[tuple[str, tuple[str, ...]], ...], str]:
    """The rig's ``plot_groups`` (as tuples) and, when the rig cannot be loaded, why."""
    from hil.rig.registry import load_rig

    if not rig:
        return (), "the record names no rig: traces are not plotted"
    try:
        groups = load_rig(rig).plot_groups
    except Exception as exc:  # an unknown or broken rig must not stop the report
        return (), f"rig {rig!r} cannot be loaded ({exc}): traces are not plotted"
    return tuple((str(t), tuple(str(s) for s in sigs)) for t, sigs in groups), ""


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def _artifacts(path: Path) -> list[str]:
    names = sorted(p.name for p in path.iterdir() if p.is_file())
    known = [n for n in KNOWN_ARTIFACTS if n in names]
    return known + [n for n in names if n not in known]


def load_run(qual: QualRecord, ref: RunRef) -> RunData:
    qual_dir = qual.path.parent
    path = qual_dir / ref.dir if ref.dir else qual_dir / "(no dir)"
    run = RunData(ref=ref, path=path, rig=qual.rig_name,
                  measurements=[m for m in qual.measurements if m.run == ref.dir])
    if ref.dir and relative_href(ref.dir) is None:
        run.notes.append(f"{ref.dir}: not a directory inside the qualification directory")
        return run
    if not ref.dir or not path.is_dir():
        run.notes.append(f"{ref.dir or '(a run without a dir)'}: run directory missing")
        return run
    run.artifacts = _artifacts(path)
    try:
        record = json.loads((path / "record.json").read_text(encoding="utf-8"))
        if isinstance(record, dict):
            run.record = record
        else:
            run.notes.append(f"{ref.dir}/record.json is not a JSON object")
    except (OSError, ValueError) as exc:
        run.notes.append(f"{ref.dir}/record.json unreadable: {exc}")
    run.rig = str(run.record.get("rig") or run.rig)
    groups, why = rig_plot_groups(run.rig)
    run.plot_groups = [(title, list(sigs)) for title, sigs in groups]
    if why:
        run.notes.append(why)
    traces = path / "traces.npz"
    if not traces.exists():
        run.notes.append(f"{ref.dir}/traces.npz missing: no plot of this run")
    else:
        try:
            run.traces, run.units = load_traces(traces)
            if "time_s" not in run.traces:
                run.notes.append(f"{ref.dir}/traces.npz has no time_s: no plot of this run")
                run.traces = None
        except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
            run.notes.append(f"{ref.dir}/traces.npz unreadable ({exc}): no plot of this run")
    truth = path / "truth.npz"
    if truth.exists():
        try:
            run.truth = _load_npz(truth)
        except (OSError, ValueError, zipfile.BadZipFile) as exc:
            run.notes.append(f"{ref.dir}/truth.npz unreadable: {exc}")
    return run


def load_runs(qual: QualRecord) -> list[RunData]:
    """Every run the record lists, then any run only a measurement names."""
    refs = list(qual.runs)
    listed = {r.dir for r in refs}
    for m in qual.measurements:
        if m.run and m.run not in listed:
            listed.add(m.run)
            refs.append(RunRef(dir=m.run, scenario="", verdict="", sim_s=None, wall_s=None))
    return [load_run(qual, ref) for ref in refs]
