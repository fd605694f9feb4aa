"""The gate: a qualification record in, a verdict for a controller build out.

Two checks, one verdict (see ``docs/qualification-record.md`` for the input):

* **limits** — every measurement's outcome as the record states it (limits come from the DUT
  profile); a failed or errored measurement fails the build;
* **regression** — each measurement against a stored baseline of the same DUT, matched by
  identity (name + sorted conditions), with a tolerance band per measurement name; a value within
  limits but worse than the baseline beyond its band is a regression.

A record whose verdict is ``invalid-bench`` or ``error`` says nothing about the DUT: the gate
reports it as a setup problem, never as a failure.

>>> from hil.gate import measurement_key
>>> measurement_key("flow.step.response_time", {"target_gps": 23, "sensor": "sliding"})
'flow.step.response_time[sensor=sliding,target_gps=23]'
"""

from hil.gate.baseline import (
    BASELINE_SCHEMA,
    Baseline,
    BaselineEntry,
    baseline_from_record,
    check_baseline_dut,
    load_baseline,
    write_baseline,
)
from hil.gate.comparison import GateResult, Row, Status, Verdict, compare, worse_by
from hil.gate.keys import format_conditions, measurement_key
from hil.gate.record import (
    RECORD_SCHEMA,
    DutIdentity,
    QualificationRecord,
    RecordMeasurement,
    load_record,
    parse_record,
)
from hil.gate.summary import render_markdown, render_text
from hil.gate.tolerance import DEFAULT_TOLERANCES, Band, Tolerances, load_tolerances

__all__ = [
    "BASELINE_SCHEMA",
    "DEFAULT_TOLERANCES",
    "RECORD_SCHEMA",
    "Band",
    "Baseline",
    "BaselineEntry",
    "DutIdentity",
    "GateResult",
    "QualificationRecord",
    "RecordMeasurement",
    "Row",
    "Status",
    "Tolerances",
    "Verdict",
    "baseline_from_record",
    "check_baseline_dut",
    "compare",
    "format_conditions",
    "load_baseline",
    "load_record",
    "load_tolerances",
    "measurement_key",
    "parse_record",
    "render_markdown",
    "render_text",
    "worse_by",
    "write_baseline",
]
