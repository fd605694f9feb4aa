"""The qualification record (``record.json`` of ``hil qualify``), read and checked for the gate.

Only what the gate uses is validated, strictly: the schema, the verdict, the DUT's identity and
every measurement's fields (see ``docs/qualification-record.md``). Anything else in the record
(tests, runs, timing, versions) is carried along untouched or ignored.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from hil.errors import ConfigError
from hil.gate.jsonfile import Fields, read_json
from hil.gate.keys import measurement_key
from hil.measurements import Measurement, Outcome

RECORD_SCHEMA = "agrihil.qualification/1"
RecordVerdict = Literal["pass", "fail", "invalid-bench", "error", "interrupted"]
RECORD_VERDICTS: tuple[RecordVerdict, ...] = ("pass", "fail", "invalid-bench", "error",
                                              "interrupted")

_SEVERITY = {Outcome.INFO: 0, Outcome.PASS: 1, Outcome.FAIL: 2, Outcome.ERROR: 3}


@dataclass(frozen=True)
class DutIdentity:
    """Who was qualified (the record's ``dut`` object, reduced to its identity)."""

    name: str
    version: str = ""
    build_id: str = ""
    kind: str = ""
    rig: str = ""
    controller: str = ""

    FIELDS = ("name", "version", "build_id", "kind", "rig", "controller")

    @classmethod
    def parse(cls, fields: Fields) -> DutIdentity:
        name = fields.string("name")
        if not name:
            raise fields.error("name", "must not be empty")
        return cls(name=name, **{k: fields.string(k, required=False) for k in cls.FIELDS[1:]})

    def to_dict(self) -> dict[str, str]:
        return {k: getattr(self, k) for k in self.FIELDS}

    def describe(self) -> str:
        """``name version (build id)``, leaving out what is empty."""
        text = self.name + (f" {self.version}" if self.version else "")
        return text + (f" (build {self.build_id})" if self.build_id else "")


@dataclass(frozen=True)
class RecordMeasurement:
    """One measurement of the record, as the gate sees it.

    ``outcome`` is the record's own; ``checked_outcome`` is the stricter of that and what the
    value and limits give (a record that says ``pass`` for a value outside its limits fails).
    """

    name: str
    value: float | None
    unit: str
    low: float | None
    high: float | None
    conditions: dict[str, Any]
    outcome: Outcome
    marginal: bool
    note: str = ""
    test: str = ""
    index: int = 0
    #: which limit applied: "profile", "profile (cond=value)" for a per-condition case,
    #: "catalogue" ... (empty in records older than per-condition limits)
    limit_source: str = ""

    @property
    def key(self) -> str:
        return measurement_key(self.name, self.conditions)

    @property
    def checked_outcome(self) -> Outcome:
        recomputed = Measurement(self.name, self.value, self.unit,  # type: ignore[arg-type]
                                 low=self.low, high=self.high).outcome
        return max(self.outcome, recomputed, key=_SEVERITY.__getitem__)


@dataclass(frozen=True)
class QualificationRecord:
    path: str
    run_id: str
    verdict: RecordVerdict
    dut: DutIdentity
    measurements: tuple[RecordMeasurement, ...]
    started_at: str = ""
    bus: str = ""
    clock: str = ""
    seed: int | None = None
    suites: tuple[str, ...] = ()
    #: the record's top-level ``limits`` (name → (low, high)), as the profile declared them
    limits: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)
    #: node ids of suite tests that did not pass (from ``tests``), for the summary
    failed_tests: tuple[str, ...] = ()
    #: False when the qualification did not run every selected test (the record's
    #: ``complete``; records written before it existed count as complete)
    complete: bool = True
    #: ``tests_completed`` / ``tests_planned`` of the record (None when absent)
    tests_completed: int | None = None
    tests_planned: int | None = None

    def incomplete_reason(self) -> str | None:
        """Why the gate must not judge this record (None: it may); the rule of
        :func:`hil.gate.completeness.incomplete_reason`, the same for every record kind."""
        from hil.gate.completeness import incomplete_reason

        return incomplete_reason({"schema": RECORD_SCHEMA, "verdict": self.verdict,
                                  "complete": self.complete,
                                  "tests_completed": self.tests_completed,
                                  "tests_planned": self.tests_planned}, path=self.path)

    def by_key(self) -> dict[str, RecordMeasurement]:
        return {m.key: m for m in self.measurements}


def load_record(path: str | Path) -> QualificationRecord:
    """Read and check a qualification record; every error names the file and the key."""
    return parse_record(read_json(path, "qualification record"), path=str(path))


def parse_record(data: Any, *, path: str) -> QualificationRecord:
    top = Fields(data, path=path)
    schema = top.string("schema")
    if schema != RECORD_SCHEMA:
        raise top.error("schema", f"expected {RECORD_SCHEMA!r}, got {schema!r} (is this a "
                                  f"qualification record of 'hil qualify'?)")
    verdict = top.string("verdict")
    if verdict not in RECORD_VERDICTS:
        raise top.error("verdict", f"{verdict!r} is not one of {list(RECORD_VERDICTS)}")
    measurements = tuple(_parse_measurement(item, path=path, index=i)
                         for i, item in enumerate(top.array("measurements")))
    seen: dict[str, int] = {}
    for m in measurements:
        if m.key in seen:
            raise ConfigError(f"duplicate measurement identity {m.key!r} (also "
                              f"measurements[{seen[m.key]}]): name and conditions must tell "
                              f"measurements apart", path=path, key=f"measurements[{m.index}]")
        seen[m.key] = m.index
    seed = top.data.get("seed")
    suites = top.array("suites", required=False)
    return QualificationRecord(
        path=path, run_id=top.string("run_id"), verdict=verdict,  # type: ignore[arg-type]
        dut=DutIdentity.parse(top.child("dut")), measurements=measurements,
        started_at=top.string("started_at", required=False),
        bus=top.string("bus", required=False), clock=top.string("clock", required=False),
        seed=seed if isinstance(seed, int) and not isinstance(seed, bool) else None,
        suites=tuple(str(s) for s in suites),
        limits=_parse_limits(top), failed_tests=_failed_tests(top),
        complete=top.data.get("complete", True) is not False,
        tests_completed=_count(top.data.get("tests_completed")),
        tests_planned=_count(top.data.get("tests_planned")))


def _count(value: Any) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _parse_measurement(item: Any, *, path: str, index: int) -> RecordMeasurement:
    f = Fields(item, path=path, prefix=f"measurements[{index}]")
    name = f.string("name")
    if not name:
        raise f.error("name", "must not be empty")
    outcome_text = f.string("outcome")
    try:
        outcome = Outcome(outcome_text)
    except ValueError:
        raise f.error("outcome", f"{outcome_text!r} is not one of "
                                 f"{[o.value for o in Outcome]}") from None
    low, high = f.number("low", required=False), f.number("high", required=False)
    if low is not None and high is not None and low > high:
        raise f.error("low", f"low limit {low:g} is above the high limit {high:g}")
    conditions = f.mapping("conditions", required=False)
    return RecordMeasurement(
        name=name, value=f.number("value"), unit=f.string("unit"), low=low, high=high,
        conditions=conditions, outcome=outcome,
        marginal=f.boolean("marginal", required=False),
        note=f.string("note", required=False), test=f.string("test", required=False),
        index=index, limit_source=f.string("limit_source", required=False))


def _parse_limits(top: Fields) -> dict[str, tuple[float | None, float | None]]:
    limits: dict[str, tuple[float | None, float | None]] = {}
    table = top.child("limits", required=False)
    for name, value in table.data.items():
        if isinstance(value, Mapping):
            entry = table.child(name)
            limits[name] = (entry.number("low", required=False),
                            entry.number("high", required=False))
    return limits


def _failed_tests(top: Fields) -> tuple[str, ...]:
    failed = []
    for test in top.array("tests", required=False):
        if isinstance(test, Mapping) and test.get("outcome") not in ("passed", "skipped", None):
            failed.append(f"{test.get('nodeid', '?')} ({test.get('outcome')})")
    return tuple(failed)
