"""The qualification record (``record.json`` of ``hil qualify``) read into typed rows.

The format is documented in ``docs/qualification-record.md``. Containers of the wrong type (a
``measurements`` that is not a list of objects, say) make the record invalid; a missing or
odd scalar is shown as it is, never guessed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.errors import HilError

SCHEMA_PREFIX = "agrihil.qualification/"
SUPPORTED_SCHEMAS = ("agrihil.qualification/1",)

#: outcome order in tables: what needs attention first
STATUS_ORDER = {"fail": 0, "error": 1, "marginal": 2, "pass": 3, "info": 4}


class ReportError(HilError, ValueError):
    """The qualification record cannot be read; the message names the file."""


def _float_or_none(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def conditions_label(conditions: dict[str, Any]) -> str:
    """The conditions as the gate keys them: sorted ``key=value`` pairs."""
    return ", ".join(f"{k}={conditions[k]}" for k in sorted(conditions))


@dataclass(frozen=True)
class MeasurementRow:
    name: str
    value: Any
    unit: str
    low: float | None
    high: float | None
    conditions: dict[str, Any]
    outcome: str
    marginal: bool
    note: str
    test: str
    run: str
    #: which limit applied (:attr:`hil.measurements.Measurement.limit_source`)
    limit_source: str = ""

    @property
    def per_condition(self) -> str:
        """For a limit stated for these conditions only, whose it is and under which
        conditions (``profile: to_mm=20``); empty for a limit of every condition."""
        layer, _, rest = self.limit_source.partition(" (")
        return f"{layer}: {rest[:-1]}" if rest.endswith(")") else ""

    @property
    def status(self) -> str:
        """fail | error | marginal | pass | info (marginal is a pass near a limit)."""
        if self.outcome == "pass" and self.marginal:
            return "marginal"
        return self.outcome if self.outcome in STATUS_ORDER else "error"

    @property
    def conditions_label(self) -> str:
        return conditions_label(self.conditions)

    @property
    def suite(self) -> str:
        return self.test.partition("::")[0] if self.test else "(no suite)"

    @property
    def test_name(self) -> str:
        return self.test.partition("::")[2] or self.test or "(no test)"

    @property
    def numeric_value(self) -> float | None:
        return _float_or_none(self.value)


@dataclass(frozen=True)
class TestRow:
    nodeid: str
    outcome: str
    duration_s: float | None
    message: str


@dataclass(frozen=True)
class RunRef:
    dir: str
    scenario: str
    verdict: str
    sim_s: float | None
    wall_s: float | None
    #: why the run did not complete, as the qualification recorded it
    error: str = ""


@dataclass(frozen=True)
class QualRecord:
    path: Path
    schema: str
    run_id: str
    started_at: str
    wall_s: float | None
    verdict: str
    dut: dict[str, Any]
    rig: dict[str, Any]
    bus: str
    clock: str
    seed: Any
    suites: list[str]
    versions: dict[str, Any]
    limits: dict[str, Any]
    measurements: list[MeasurementRow]
    tests: list[TestRow]
    runs: list[RunRef]
    timing: dict[str, Any] | None
    error: str
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def rig_name(self) -> str:
        return str(self.rig.get("name") or self.dut.get("rig") or "")

    def counts(self) -> dict[str, int]:
        """Measurements per status, each counted once (``pass`` without the marginal ones),
        so the counts add up to the number of measurements."""
        out = dict.fromkeys(("pass", "marginal", "fail", "error", "info"), 0)
        for m in self.measurements:
            out[m.status] += 1
        return out


class _Reader:
    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, message: str) -> ReportError:
        return ReportError(f"{self.path}: {message}")

    def obj(self, raw: Any, key: str) -> dict[str, Any]:
        if raw is None:
            return {}
        if not isinstance(raw, dict):
            raise self.fail(f"'{key}' must be an object, not {type(raw).__name__}")
        return raw

    def objects(self, raw: Any, key: str) -> list[dict[str, Any]]:
        if raw is None:
            return []
        if not isinstance(raw, list):
            raise self.fail(f"'{key}' must be a list, not {type(raw).__name__}")
        for i, item in enumerate(raw):
            if not isinstance(item, dict):
                raise self.fail(f"'{key}[{i}]' must be an object, not {type(item).__name__}")
        return raw


def _text(value: Any) -> str:
    return "" if value is None else str(value)


def _measurement(d: dict[str, Any]) -> MeasurementRow:
    conditions = d.get("conditions")
    return MeasurementRow(
        name=_text(d.get("name")) or "(unnamed)", value=d.get("value"),
        unit=_text(d.get("unit")), low=_float_or_none(d.get("low")),
        high=_float_or_none(d.get("high")),
        conditions=conditions if isinstance(conditions, dict) else {},
        outcome=_text(d.get("outcome")) or "error", marginal=bool(d.get("marginal")),
        note=_text(d.get("note")), test=_text(d.get("test")), run=_text(d.get("run")),
        limit_source=_text(d.get("limit_source")))


def load_qualification(qual_dir: Path) -> QualRecord:
    """Read ``qual_dir/record.json``; :class:`ReportError` naming the file when it is missing,
    not JSON, or not a qualification record."""
    path = Path(qual_dir) / "record.json"
    reader = _Reader(path)
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise reader.fail("no qualification record here (written by 'hil qualify')") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise reader.fail(f"cannot read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise reader.fail(f"not valid JSON: {exc}") from None
    if not isinstance(raw, dict):
        raise reader.fail(f"must hold a JSON object, not {type(raw).__name__}")
    schema = raw.get("schema")
    if not isinstance(schema, str) or not schema.startswith(SCHEMA_PREFIX):
        raise reader.fail(f"not a qualification record: schema is {schema!r}, expected "
                          f"{SUPPORTED_SCHEMAS[-1]!r} (a single run's record.json is not one)")
    if schema not in SUPPORTED_SCHEMAS:
        raise reader.fail(f"unsupported schema {schema!r}; this agrihil reads "
                          f"{', '.join(SUPPORTED_SCHEMAS)}")
    suites = raw.get("suites")
    timing = raw.get("timing")
    known = {"schema", "run_id", "started_at", "wall_s", "verdict", "dut", "rig", "bus", "clock",
             "seed", "suites", "versions", "limits", "measurements", "tests", "runs", "timing",
             "error"}
    return QualRecord(
        path=path, schema=schema, run_id=_text(raw.get("run_id")),
        started_at=_text(raw.get("started_at")), wall_s=_float_or_none(raw.get("wall_s")),
        verdict=_text(raw.get("verdict")) or "error",
        dut=reader.obj(raw.get("dut"), "dut"), rig=reader.obj(raw.get("rig"), "rig"),
        bus=_text(raw.get("bus")), clock=_text(raw.get("clock")), seed=raw.get("seed"),
        suites=[str(s) for s in suites] if isinstance(suites, list) else [],
        versions=reader.obj(raw.get("versions"), "versions"),
        limits=reader.obj(raw.get("limits"), "limits"),
        measurements=[_measurement(d) for d in
                      reader.objects(raw.get("measurements"), "measurements")],
        tests=[TestRow(nodeid=_text(d.get("nodeid")), outcome=_text(d.get("outcome")),
                       duration_s=_float_or_none(d.get("duration_s")),
                       message=_text(d.get("message")))
               for d in reader.objects(raw.get("tests"), "tests")],
        runs=[RunRef(dir=_text(d.get("dir")), scenario=_text(d.get("scenario")),
                     verdict=_text(d.get("verdict")), sim_s=_float_or_none(d.get("sim_s")),
                     wall_s=_float_or_none(d.get("wall_s")), error=_text(d.get("error")))
              for d in reader.objects(raw.get("runs"), "runs")],
        timing=reader.obj(timing, "timing") if timing is not None else None,
        error=_text(raw.get("error")),
        extra={k: v for k, v in raw.items() if k not in known})
