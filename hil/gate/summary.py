"""What the gate says: a Markdown page for CI (a GitHub step summary) and a few terminal lines.

Both are pure functions of a :class:`~hil.gate.comparison.GateResult`; the caller writes them.
The Markdown starts with the verdict line and the reasons, then a table of what needs a look
(failures, errors, missing measurements, regressions, marginal values, bus checks included),
then the control measurements (measurement, conditions, value, limits, baseline, delta,
status; worst first), then bus conformance as one line per run.
"""

from __future__ import annotations

from hil.gate.comparison import GateResult, Row, Status, Verdict
from hil.gate.keys import format_conditions
from hil.limits import is_conformance

_LABEL = {Verdict.PASS: "PASS", Verdict.FAIL: "FAIL",
          Verdict.INVALID_BENCH: "INVALID BENCH (no verdict on the DUT)",
          Verdict.ERROR: "ERROR (the qualification did not run)"}
_ICON = {Verdict.PASS: "✅", Verdict.FAIL: "❌", Verdict.INVALID_BENCH: "⚠️",
         Verdict.ERROR: "⚠️"}
_LOUD = (Status.FAIL, Status.ERROR, Status.MISSING, Status.REGRESSION)
#: rows of the "needs a look" table, whatever their kind
_LOOK = (*_LOUD, Status.MARGINAL)
#: statuses listed one by one in the terminal summary
_LISTED = (Status.FAIL, Status.ERROR, Status.MISSING, Status.REGRESSION, Status.MARGINAL,
           Status.IMPROVED, Status.NEW)


def render_markdown(result: GateResult, *, baseline_written: str = "") -> str:
    """The CI page: the verdict and why; what needs a look (failures, errors, missing
    measurements, regressions, marginal values), whatever kind; the control measurements;
    then bus conformance, one line per run (its checks that need a look are in the first
    table); notes last."""
    record = result.record
    lines = [f"### {_ICON[result.verdict]} agrihil gate: {_LABEL[result.verdict]} — "
             f"{_md(record.dut.describe())}", ""]
    lines.append(" · ".join(_sources(result, code=True)))
    lines.append("")
    lines += [f"- {_md(reason)}" for reason in result.reasons]
    lines += [f"- warning: {_md(warning)}" for warning in result.warnings]
    if baseline_written:
        lines.append(f"- baseline written to `{baseline_written}`")
    if result.reasons or result.warnings or baseline_written:
        lines.append("")
    counts = ", ".join(f"{n} {status.value}" for status, n in result.counts().items())
    lines += [f"{len(result.rows)} measurements: {counts or 'none'}", ""]
    look = [row for row in result.rows if row.status in _LOOK]
    control = [row for row in result.rows
               if row.status not in _LOOK and not _is_bus(row.name)]
    bus = [row for row in result.rows if _is_bus(row.name)]
    if look:
        lines += [f"#### Needs a look ({len(look)})", "", *_table(look), ""]
    if control:
        lines += [f"#### Control measurements ({len(control)})", "", *_table(control), ""]
    if bus:
        lines += _bus_lines(bus)
    notes = [f"{_code(row.key)}: {_md(note)}" for row in result.rows for note in row.notes]
    notes += [_md(note) for note in result.notes]
    if notes:
        lines.append("Notes:")
        lines += [f"- {note}" for note in notes]
        lines.append("")
    return "\n".join(lines)


def _is_bus(name: str) -> bool:
    """A bus conformance measurement (folded into one line per run unless it needs a look)."""
    return is_conformance(name)


def _table(rows: list[Row]) -> list[str]:
    lines = ["| measurement | conditions | value | limits | baseline | delta | status |",
             "|---|---|---:|---|---:|---:|---|"]
    for row in rows:
        status = f"**{row.status.value}**" if row.status in _LOUD else row.status.value
        cells = [_md(c) for c in (format_conditions(row.conditions),
                                  _quantity(row.value, row.unit),
                                  _limits(row.low, row.high, ascii_=False),
                                  _quantity(row.baseline, row.unit), _delta(row))]
        lines.append("| " + " | ".join([_code(row.name), *cells, status]) + " |")
    return lines


def _bus_lines(rows: list[Row]) -> list[str]:
    """Bus conformance, one line per run: how many checks and their statuses (those that
    need a look are in the table above, and said so)."""
    by_run: dict[str, list[Row]] = {}
    for row in rows:
        by_run.setdefault(str(row.conditions.get("run", "—")), []).append(row)
    lines = [f"#### Bus conformance ({len(by_run)} runs, {len(rows)} checks)", ""]
    for run, run_rows in sorted(by_run.items()):
        statuses: dict[str, int] = {}
        for row in run_rows:
            statuses[row.status.value] = statuses.get(row.status.value, 0) + 1
        counts = ", ".join(f"{n} {status}" for status, n in statuses.items())
        above = " (see above)" if any(row.status in _LOOK for row in run_rows) else ""
        lines.append(f"- {_code(run)}: {len(run_rows)} checks: {counts}{above}")
    lines.append("")
    return lines


def render_text(result: GateResult, *, baseline_written: str = "") -> str:
    record = result.record
    lines = [f"hil gate: {_LABEL[result.verdict]}: {record.dut.describe()}, run "
             f"{record.run_id}"]
    counts = ", ".join(f"{n} {status.value}" for status, n in result.counts().items())
    lines.append(f"  {len(result.rows)} measurements: {counts or 'none'}")
    lines.append("  " + "; ".join(_sources(result, code=False)))
    width = max((len(row.status.value) for row in result.rows), default=0)
    for row in result.rows:
        if row.status not in _LISTED:
            continue
        value = "no value" if row.value is None else _quantity(row.value, row.unit)
        if row.status is Status.MISSING:
            value = "not in the record"
        text = f"  {row.status.value:<{width}}  {row.key}: {value}"
        if row.status in (Status.FAIL, Status.MARGINAL):
            text += f" (limits {_limits(row.low, row.high, ascii_=True)})"
        if row.baseline is not None:
            text += f", baseline {_quantity(row.baseline, row.unit)}"
        if row.delta is not None and row.status in (Status.REGRESSION, Status.IMPROVED):
            text += f" ({_delta(row, band_sep=', ')})"
        lines.append(text)
    lines += [f"  why: {reason}" for reason in result.reasons]
    lines += [f"  warning: {warning}" for warning in result.warnings]
    if baseline_written:
        lines.append(f"  baseline written to {baseline_written}")
    return "\n".join(lines)


def _sources(result: GateResult, *, code: bool) -> list[str]:
    def q(text: str) -> str:
        return _code(text) if code else text

    record = result.record
    run = ", ".join(x for x in (record.bus, record.clock,
                                "suites " + "+".join(record.suites) if record.suites else "")
                    if x)
    parts = [f"record {q(record.path)} (run {record.run_id}{', ' + run if run else ''})"]
    if result.baseline is not None:
        when = result.baseline.created_at[:10]
        parts.append(f"baseline {q(result.baseline.path or '?')} (run "
                     f"{result.baseline.source_run_id}{', ' + when if when else ''})")
        tolerances = result.tolerances
        parts.append(f"tolerances {q(tolerances.path)}" if tolerances.path
                     else f"tolerances: {tolerances.describe()}")
    else:
        parts.append("no baseline: limits only")
    return parts


def _num(value: float) -> str:
    return f"{value:.5g}"


def _quantity(value: float | None, unit: str) -> str:
    if value is None:
        return "—"
    return f"{_num(value)} {unit}".rstrip()


def _limits(low: float | None, high: float | None, *, ascii_: bool) -> str:
    le, ge, dash = ("<=", ">=", "..") if ascii_ else ("≤", "≥", " to ")
    if low is None and high is None:
        return "-" if ascii_ else "—"
    if low is None:
        return f"{le} {_num(high)}" if high is not None else ""
    if high is None:
        return f"{ge} {_num(low)}"
    return f"{_num(low)}{dash}{_num(high)}"


def _delta(row: Row, *, band_sep: str = " ") -> str:
    """``+0.18 s``; for a regression or an improvement also the band it went beyond."""
    if row.delta is None:
        return "—"
    text = f"{row.delta:+.4g} {row.unit}".rstrip()
    if row.band is not None and row.status in (Status.REGRESSION, Status.IMPROVED):
        band = f"band {row.band:.4g} {row.unit}".rstrip()
        text += f"{band_sep}({band})" if band_sep == " " else f"{band_sep}{band}"
    return text


def _code(text: str) -> str:
    """A code span (shown verbatim, so only the table's pipe needs escaping)."""
    return "`" + text.replace("`", "'").replace("|", "\\|").replace("\n", " ") + "`"


def _md(text: str) -> str:
    """One table cell or list item: no pipes or line breaks that would break the table, no
    ``<…>`` that GitHub would take for (and strip as) HTML."""
    return (text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            .replace("|", "\\|").replace("\n", " "))
