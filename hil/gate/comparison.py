"""Limits plus regression: one row per measurement identity, one verdict for the build.

Which way is worse follows from the limits (:func:`worse_by`): only ``high`` → larger is worse;
only ``low`` → smaller is worse; both → farther from the middle of the band is worse; none → the
measurement is information and never regresses.

>>> worse_by(1.3, 1.1, low=None, high=1.5) > 0        # a slower response: worse
True
>>> worse_by(97.0, 96.0, low=95.0, high=None) < 0     # a better accuracy
True
>>> worse_by(31.0, 29.5, low=20.0, high=40.0)         # 1 mm from the centre instead of 0.5
0.5
>>> worse_by(5.0, 1.0, low=None, high=None) is None
True
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from hil.gate.baseline import Baseline, BaselineEntry
from hil.gate.record import QualificationRecord, RecordMeasurement
from hil.gate.tolerance import DEFAULT_TOLERANCES, Tolerances
from hil.measurements import Outcome


class Status(StrEnum):
    FAIL = "FAIL"
    ERROR = "ERROR"
    MISSING = "missing"
    REGRESSION = "regression"
    MARGINAL = "marginal"
    IMPROVED = "improved"
    NEW = "new"
    PASS = "pass"
    INFO = "info"


#: statuses in the order the summary lists them (worst first)
STATUS_ORDER = tuple(Status)


class Verdict(StrEnum):
    PASS = "pass"
    FAIL = "fail"
    #: the bench, not the DUT, was at fault (real-time timing out of bounds): no verdict
    INVALID_BENCH = "invalid-bench"
    #: the qualification could not run
    ERROR = "error"

    @property
    def exit_code(self) -> int:
        return {Verdict.PASS: 0, Verdict.FAIL: 1}.get(self, 2)


@dataclass(frozen=True)
class Row:
    """One measurement identity: its value now, its baseline, and what the gate makes of it."""

    key: str
    name: str
    conditions: dict[str, Any]
    unit: str
    value: float | None
    low: float | None
    high: float | None
    status: Status
    baseline: float | None = None
    #: value - baseline (signed, raw)
    delta: float | None = None
    #: the tolerance band's width around the baseline, in the unit, and where it came from
    band: float | None = None
    band_source: str = ""
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class GateResult:
    record: QualificationRecord
    baseline: Baseline | None
    tolerances: Tolerances
    rows: tuple[Row, ...]
    verdict: Verdict
    #: why the verdict is not pass (one line each), then warnings that did not fail it
    reasons: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    @property
    def exit_code(self) -> int:
        return self.verdict.exit_code

    def count(self, status: Status) -> int:
        return sum(1 for row in self.rows if row.status is status)

    def counts(self) -> dict[Status, int]:
        tally = Counter(row.status for row in self.rows)
        return {s: tally[s] for s in STATUS_ORDER if tally[s]}


def worse_by(value: float, reference: float, *, low: float | None,
             high: float | None) -> float | None:
    """How much worse ``value`` is than ``reference`` (negative: better), or ``None`` when the
    limits give no direction."""
    if low is not None and high is not None:
        centre = 0.5 * (low + high)
        return abs(value - centre) - abs(reference - centre)
    if high is not None:
        return value - reference
    if low is not None:
        return reference - value
    return None


def compare(record: QualificationRecord, baseline: Baseline | None,
            tolerances: Tolerances = DEFAULT_TOLERANCES, *, allow_regressions: bool = False,
            accept_changes: bool = False, notes: tuple[str, ...] = ()) -> GateResult:
    """Gate ``record``: limits, then regression against ``baseline`` when there is one.

    ``allow_regressions`` turns regressions into warnings. ``accept_changes`` (when a new baseline
    is being written) judges the record by its limits only: regressions and missing
    measurements are shown but accepted.
    """
    entries = baseline.entries if baseline else {}
    rows = [_row(m, entries.get(m.key), tolerances, has_baseline=baseline is not None)
            for m in record.measurements]
    present = {m.key for m in record.measurements}
    rows += [_missing_row(entry) for key, entry in entries.items() if key not in present]
    rows.sort(key=lambda row: STATUS_ORDER.index(row.status))
    all_notes = list(notes) + _record_notes(record, baseline)
    verdict, reasons, warnings = _verdict(record, rows, allow_regressions=allow_regressions,
                                          accept_changes=accept_changes)
    return GateResult(record=record, baseline=baseline, tolerances=tolerances, rows=tuple(rows),
                      verdict=verdict, reasons=tuple(reasons), warnings=tuple(warnings),
                      notes=tuple(all_notes))


def _row(m: RecordMeasurement, entry: BaselineEntry | None, tolerances: Tolerances, *,
         has_baseline: bool) -> Row:
    notes: list[str] = []
    outcome = m.checked_outcome
    if outcome is not m.outcome:
        notes.append(f"the record says {m.outcome.value} but value and limits give "
                     f"{outcome.value}")
    baseline_value = delta = band = None
    band_source = ""
    direction: float | None = None
    if entry is not None:
        baseline_value = entry.value
        if entry.unit != m.unit:
            notes.append(f"unit changed from {entry.unit!r} to {m.unit!r}: not compared")
        elif m.value is not None and entry.value is not None:
            delta = m.value - entry.value
            band_spec, band_source = tolerances.band_for(m.name)
            band = band_spec.width(entry.value)
            direction = worse_by(m.value, entry.value, low=m.low, high=m.high)
        if (entry.low, entry.high) != (m.low, m.high):
            notes.append(f"limits changed since the baseline (were "
                         f"{_limits(entry.low, entry.high)})")
    status = _status(m, outcome, entry, direction, band, has_baseline=has_baseline)
    return Row(key=m.key, name=m.name, conditions=m.conditions, unit=m.unit, value=m.value,
               low=m.low, high=m.high, status=status, baseline=baseline_value, delta=delta,
               band=band, band_source=band_source,
               notes=tuple(notes + ([m.note] if m.note else [])))


def _status(m: RecordMeasurement, outcome: Outcome, entry: BaselineEntry | None,
            direction: float | None, band: float | None, *, has_baseline: bool) -> Status:
    if outcome is Outcome.FAIL:
        return Status.FAIL
    if outcome is Outcome.ERROR:
        return Status.ERROR
    if has_baseline and entry is None:
        return Status.NEW
    if direction is not None and band is not None and entry is not None:
        # a hair of slack so that float noise on an unchanged value never regresses
        slack = band + 1e-9 * max(1.0, abs(entry.value or 0.0))
        if direction > slack:
            return Status.REGRESSION
        if direction < -slack:
            return Status.IMPROVED
    if m.marginal:
        return Status.MARGINAL
    return Status.INFO if outcome is Outcome.INFO else Status.PASS


def _missing_row(entry: BaselineEntry) -> Row:
    return Row(key=entry.key, name=entry.name, conditions=entry.conditions, unit=entry.unit,
               value=None, low=entry.low, high=entry.high, status=Status.MISSING,
               baseline=entry.value, notes=("in the baseline, not in the record: a check "
                                            "disappeared",))


def _verdict(record: QualificationRecord, rows: list[Row], *, allow_regressions: bool,
             accept_changes: bool) -> tuple[Verdict, list[str], list[str]]:
    tally = Counter(row.status for row in rows)
    reasons: list[str] = []
    warnings: list[str] = []
    if record.verdict == "error":
        return Verdict.ERROR, ["the qualification could not run (record verdict 'error'): "
                               "no verdict on the DUT"], warnings
    if record.verdict == "invalid-bench":
        return Verdict.INVALID_BENCH, ["the bench was invalid (real-time timing out of "
                                       "bounds): neither pass nor fail for the DUT; rerun "
                                       "on a quieter machine or in lockstep"], warnings
    if not record.measurements:
        reasons.append("the record has no measurements: nothing was checked")
    if tally[Status.FAIL]:
        reasons.append(f"{_n(tally[Status.FAIL], 'measurement')} outside limits")
    if tally[Status.ERROR]:
        reasons.append(f"{_n(tally[Status.ERROR], 'measurement')} could not be computed")
    if record.verdict == "fail" and not (tally[Status.FAIL] or tally[Status.ERROR]):
        reasons.append("the record's verdict is fail" + (
            f" (tests: {'; '.join(record.failed_tests)})" if record.failed_tests else ""))
    regressions, missing = tally[Status.REGRESSION], tally[Status.MISSING]
    if regressions:
        text = f"{_n(regressions, 'regression')} beyond tolerance"
        if accept_changes:
            warnings.append(f"{text} (accepted: the baseline is being updated)")
        elif allow_regressions:
            warnings.append(f"{text} (allowed: --allow-regressions)")
        else:
            reasons.append(text)
    if missing:
        text = f"{_n(missing, 'baseline measurement')} missing from the record"
        if accept_changes:
            warnings.append(f"{text} (accepted: the baseline is being updated)")
        else:
            reasons.append(text)
    if tally[Status.MARGINAL]:
        warnings.append(f"{_n(tally[Status.MARGINAL], 'measurement')} marginal (close to "
                        f"a limit)")
    return (Verdict.FAIL if reasons else Verdict.PASS), reasons, warnings


def _record_notes(record: QualificationRecord, baseline: Baseline | None) -> list[str]:
    notes = []
    names = {m.name for m in record.measurements}
    unchecked = sorted(name for name in record.limits if name not in names)
    if unchecked:
        notes.append(f"limits in the profile with no measurement in this record: "
                     f"{', '.join(unchecked)}")
    for m in record.measurements:
        declared = record.limits.get(m.name)
        # a per-condition case ("profile (to_mm=20)") has its own band, not the entry's
        per_case = m.limit_source not in ("", "profile")
        if declared is not None and not per_case and declared != (m.low, m.high):
            notes.append(f"{m.key}: its limits {_limits(m.low, m.high)} differ from the "
                         f"record's limits table {_limits(*declared)}")
    if baseline is not None:
        for what in ("clock", "bus"):
            then, now = baseline.source.get(what), getattr(record, what)
            if then and now and then != now:
                notes.append(f"the baseline was recorded with {what} {then!r}, this record "
                             f"with {now!r}")
    return notes


def _limits(low: float | None, high: float | None) -> str:
    if low is None and high is None:
        return "none"
    if low is None:
        return f"<= {high:g}"
    if high is None:
        return f">= {low:g}"
    return f"{low:g}..{high:g}"


def _n(count: int, noun: str) -> str:
    return f"{count} {noun}{'' if count == 1 else 's'}"
