"""The stored baseline: a reduced qualification record a build is compared against.

Written deliberately (``hil gate RECORD --baseline PATH --update-baseline``), reviewed like code::

    {
      "schema": "agrihil.baseline/1",
      "dut": {"name": "…", "version": "…", "build_id": "…", "kind": "…", "rig": "…",
              "controller": "…"},
      "source": {"run_id": "…", "started_at": "…", "bus": "…", "clock": "…", "seed": 1,
                 "suites": ["fast"]},
      "created_at": "2026-11-22T10:05:00+00:00",
      "measurements": {
        "flow.step.response_time[sensor=sliding,target_gps=23]": {
          "name": "flow.step.response_time", "conditions": {"sensor": "sliding", "target_gps": 23},
          "value": 1.12, "unit": "s", "low": null, "high": 1.5}
      }
    }

Each entry's key must be the identity of its ``name`` and ``conditions`` (see
:func:`hil.gate.keys.measurement_key`), so a hand edit cannot silently detach an entry.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from hil.errors import ConfigError
from hil.gate.jsonfile import Fields, read_json, write_json
from hil.gate.keys import measurement_key
from hil.gate.record import DutIdentity, QualificationRecord

BASELINE_SCHEMA = "agrihil.baseline/1"


@dataclass(frozen=True)
class BaselineEntry:
    name: str
    conditions: dict[str, Any]
    value: float | None
    unit: str
    low: float | None = None
    high: float | None = None

    @property
    def key(self) -> str:
        return measurement_key(self.name, self.conditions)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "conditions": self.conditions, "value": self.value,
                "unit": self.unit, "low": self.low, "high": self.high}


@dataclass(frozen=True)
class Baseline:
    dut: DutIdentity
    source_run_id: str
    created_at: str
    entries: dict[str, BaselineEntry]
    #: where the source record came from: started_at, bus, clock, seed, suites
    source: dict[str, Any] = field(default_factory=dict)
    path: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"schema": BASELINE_SCHEMA, "dut": self.dut.to_dict(),
                "source": {"run_id": self.source_run_id, **self.source},
                "created_at": self.created_at,
                "measurements": {key: self.entries[key].to_dict()
                                 for key in sorted(self.entries)}}


def baseline_from_record(record: QualificationRecord, *, created_at: datetime,
                         path: str = "") -> Baseline:
    """The baseline a record makes: its DUT identity, its run, every measurement's value."""
    entries = {m.key: BaselineEntry(name=m.name, conditions=dict(m.conditions), value=m.value,
                                    unit=m.unit, low=m.low, high=m.high)
               for m in record.measurements}
    source = {"started_at": record.started_at, "bus": record.bus, "clock": record.clock,
              "seed": record.seed, "suites": list(record.suites)}
    return Baseline(dut=record.dut, source_run_id=record.run_id,
                    created_at=created_at.isoformat(timespec="seconds"), entries=entries,
                    source=source, path=path)


def write_baseline(baseline: Baseline, path: str | Path) -> None:
    write_json(path, baseline.to_dict())


def load_baseline(path: str | Path) -> Baseline:
    """Read and check a baseline; every error names the file and the key."""
    path = str(path)
    if not Path(path).exists():
        raise ConfigError(f"baseline not found (write one from a passing record with "
                          f"'hil gate RECORD --baseline {path} --update-baseline')", path=path)
    top = Fields(read_json(path, "baseline"), path=path)
    schema = top.string("schema")
    if schema != BASELINE_SCHEMA:
        raise top.error("schema", f"expected {BASELINE_SCHEMA!r}, got {schema!r} (write a "
                                  f"baseline with 'hil gate RECORD --baseline {path} "
                                  f"--update-baseline')")
    source = top.child("source")
    run_id = source.string("run_id")
    measurements = top.child("measurements")
    entries: dict[str, BaselineEntry] = {}
    for key in measurements.data:
        f = measurements.child(key)
        entry = BaselineEntry(name=f.string("name"), conditions=f.mapping("conditions"),
                              value=f.number("value"), unit=f.string("unit"),
                              low=f.number("low", required=False),
                              high=f.number("high", required=False))
        if entry.key != key:
            raise ConfigError(f"key does not match its name and conditions (expected "
                              f"{entry.key!r})", path=path, key=f"measurements.{key}")
        entries[key] = entry
    return Baseline(dut=DutIdentity.parse(top.child("dut")), source_run_id=run_id,
                    created_at=top.string("created_at", required=False), entries=entries,
                    source={k: v for k, v in source.data.items() if k != "run_id"}, path=path)


def check_baseline_dut(baseline: Baseline, record: QualificationRecord, *,
                       force: bool) -> list[str]:
    """A baseline of another DUT is an error unless ``force``; returns notes for the summary."""
    if baseline.dut.name == record.dut.name:
        return []
    message = (f"baseline is of DUT {baseline.dut.name!r}, the record of {record.dut.name!r}")
    if not force:
        raise ConfigError(f"{message}; compare them anyway with --force", path=baseline.path,
                          key="dut.name")
    return [f"{message}: compared anyway (--force)"]
