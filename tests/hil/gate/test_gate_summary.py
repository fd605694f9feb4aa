"""The summaries are plain functions of a gate result: check what they print."""

from __future__ import annotations

from datetime import UTC, datetime

from hil.gate import (
    Band,
    Tolerances,
    baseline_from_record,
    compare,
    parse_record,
    render_markdown,
    render_text,
)
from hil.measurements import Measurement

from .records import record


def test_markdown_cells_never_break_the_table_or_turn_into_html() -> None:
    m = Measurement("flow.step.overshoot", 12.0, "%", high=10.0,
                    conditions={"sensor": "a|b", "label": "<x>"}, note="line 1\nline 2")
    result = compare(parse_record(record([m]), path="r.json"), None)
    lines = render_markdown(result).splitlines()
    (row,) = [line for line in lines if line.startswith("| `flow")]
    assert row == ("| `flow.step.overshoot` | label=&lt;x&gt;, sensor=a\\|b | 12 % | ≤ 10 | — | — "
                   "| **FAIL** |")
    assert row.count(" | ") == 6
    # in a code span only the pipe is escaped: GitHub shows the rest verbatim
    assert "- `flow.step.overshoot[label=<x>,sensor=a\\|b]`: line 1 line 2" in lines


def test_the_text_summary_lists_what_needs_a_look_and_why() -> None:
    ms = [Measurement("flow.step.response_time", 1.49, "s", high=1.5),
          Measurement("flow.bench.accuracy", 97.0, "%", low=90.0)]
    base_rec = parse_record(record([Measurement("flow.step.response_time", 1.49, "s", high=1.5),
                                    Measurement("flow.bench.accuracy", 95.0, "%", low=90.0)]),
                            path="b.json")
    base = baseline_from_record(base_rec, created_at=datetime(2026, 1, 2, tzinfo=UTC),
                                path="base.json")
    result = compare(parse_record(record(ms), path="r.json"), base,
                     Tolerances(default=Band(abs=0.5), path="tol.toml"))
    assert render_text(result).splitlines() == [
        "hil gate: PASS: fertilizer-piecewise-pid-firmware 1.0.0 (build b-0001), run "
        "3f2a9c1b7d10",
        "  2 measurements: 1 marginal, 1 improved",
        "  record r.json (run 3f2a9c1b7d10, softbus, lockstep, suites fast); baseline base.json "
        "(run 3f2a9c1b7d10, 2026-01-02); tolerances tol.toml",
        "  marginal  flow.step.response_time: 1.49 s (limits <= 1.5), baseline 1.49 s",
        "  improved  flow.bench.accuracy: 97 %, baseline 95 % (+2 %, band 0.5 %)",
        "  warning: 1 measurement marginal (close to a limit)",
    ]
