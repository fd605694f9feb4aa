"""The tables: measurements against limits, runs with their artifacts, tests, errors."""

from __future__ import annotations

from collections import Counter
from itertools import groupby
from typing import Any

from hil.effective_limits import RecordedLimit, origin_of
from hil.errors import ConfigError
from hil.limits import MEASUREMENTS, limit_text
from hil.report.markup import (
    DASH,
    badge,
    esc,
    fmt_num,
    fmt_seconds,
    link,
    note,
    pre,
    row,
    table,
)
from hil.report.record import STATUS_ORDER, MeasurementRow, QualRecord
from hil.report.rundata import RunData

MEASUREMENT_HEADERS = ("name", "conditions", "value", "unit", "low", "high", "outcome", "run")
MAX_MESSAGE = 800


def _outcome_badge(m: MeasurementRow) -> str:
    if m.status == "marginal":
        return badge("marginal", "PASS · MARGINAL")
    return badge(m.status)


def _measurement_row(m: MeasurementRow, anchors: dict[str, str]) -> str:
    # a break opportunity after every dot: long names wrap at their parts on paper
    name = f"<code>{esc(m.name).replace('.', '.<wbr>')}</code>"
    if m.note:
        name += f'<div class="small">{esc(m.note)}</div>'
    run = DASH
    if m.run:
        anchor = anchors.get(m.run)
        label = esc(m.run.rsplit("/", 1)[-1])
        run = f'<a href="#{esc(anchor)}">{label}</a>' if anchor else label
    cells = [name, esc(m.conditions_label) or DASH,
             f'<span class="num">{esc(fmt_num(m.value))}</span>', esc(m.unit),
             *_limit_cells(m), _outcome_badge(m), run]
    return row(cells, f"m-{m.status}")


def _limit_cells(m: MeasurementRow) -> list[str]:
    """The low and high cells; a limit stated for these conditions only says so under it."""
    cells = [esc(fmt_num(m.low)), esc(fmt_num(m.high))]
    if m.per_condition:
        at = 1 if m.high is not None or m.low is None else 0
        cells[at] += f'<div class="small">per condition ({esc(m.per_condition)})</div>'
    return cells


def _group_rank(ms: list[MeasurementRow]) -> int:
    return min(STATUS_ORDER[m.status] for m in ms)


def measurements_section(qual: QualRecord, runs: list[RunData]) -> str:
    anchors = {r.ref.dir: r.anchor for r in runs}
    if not qual.measurements:
        body = note("the record holds no measurements")
    else:
        keyed = sorted(qual.measurements, key=lambda m: (m.suite, m.test_name))
        groups = [(key, list(ms)) for key, ms in
                  groupby(keyed, key=lambda m: (m.suite, m.test_name))]
        # groups that need attention first; inside a group: fail, error, marginal, pass, info
        groups.sort(key=lambda g: _group_rank(g[1]))
        rows = []
        for (suite, test), ms in groups:
            rows.append(f'<tr class="group"><th colspan="{len(MEASUREMENT_HEADERS)}">'
                        f'<span class="small">{esc(suite)}</span> <b>{esc(test)}</b></th></tr>')
            ordered = sorted(ms, key=lambda m: STATUS_ORDER[m.status])
            rows += [_measurement_row(m, anchors) for m in ordered]
        body = table(MEASUREMENT_HEADERS, rows, "measurements")
    measured = {m.name for m in qual.measurements}
    unmeasured = [name for name in qual.limits if name not in measured]
    if unmeasured:
        body += note("limits with no measurement in this record: " + ", ".join(unmeasured))
    body += profile_limits_table(qual.limits)
    return f"""
<section id="measurements">
  <h2>Measurements against limits</h2>
  <p class="small">Grouped by suite and test; groups and rows that need attention come first.
  The identity of a measurement is its name plus its conditions.</p>
  {body}
</section>"""


PROFILE_LIMIT_HEADERS = ("name", "limit", "against the catalogue's default", "reason")


def profile_limits_table(limits: dict[str, Any]) -> str:
    """The profile's own limits, each against the catalogue's default: the same, tightened,
    loosened (with the profile's reason), or set where the catalogue judges nothing. Every
    measurement the profile names no limit for is judged by the default (the catalogue page,
    ``hil limits``)."""
    rows = []
    loosened = 0
    for name, entry in sorted(limits.items()):
        if not isinstance(entry, dict) or name not in MEASUREMENTS:
            continue
        try:
            stated = RecordedLimit.parse(entry)
        except ConfigError:
            continue
        spec = MEASUREMENTS[name]
        origin = str(entry.get("origin") or origin_of(name, stated))
        default = limit_text(spec.low, spec.high, spec.cases, otherwise="none") \
            if not spec.default_rule else spec.default_rule
        against = {"default": "the default", "set": "set (the catalogue has none)"}.get(
            origin, f"{origin} (default {default})")
        source = spec.source or spec.information
        reason = stated.reason or ("(not recorded: see the profile)" if origin == "loosened"
                                   else "")
        loosened += origin == "loosened"
        rows.append(row([f"<code>{esc(name)}</code>",
                         esc(limit_text(stated.low, stated.high, stated.cases,
                                        otherwise="the default") + f" {spec.unit}"),
                         esc(against) + (f'<div class="small">from {esc(source)}</div>'
                                         if source else ""),
                         esc(reason) or DASH], f"limit-{origin}"))
    if not rows:
        return note("the profile sets no limit of its own: every measurement is judged by "
                    "the catalogue's default")
    return (f'<h3>The profile\'s own limits</h3><p class="small">{len(rows)} of the profile; '
            f"{loosened} looser than the catalogue's default (each with its reason). Every "
            "other measurement is judged by the catalogue's default.</p>"
            + table(PROFILE_LIMIT_HEADERS, rows, "profile-limits"))


def _timing_cell(run: RunData) -> str:
    timing = run.timing
    mode = timing.get("mode")
    if not mode:
        return DASH
    if mode != "realtime":
        return esc(mode)
    p99 = timing.get("lateness_p99_s")
    text = f"realtime, p99 {p99 * 1e6:.0f} µs" if isinstance(p99, int | float) else "realtime"
    return esc(text) + ("" if timing.get("valid", True) else " " + badge("invalid-bench"))


def gnss_epochs(run: RunData) -> dict[str, float] | None:
    """The run's GNSS serial epoch counts (``truth.gnss_epochs``), None when it has none."""
    truth = run.record.get("truth")
    counts = truth.get("gnss_epochs") if isinstance(truth, dict) else None
    if not isinstance(counts, dict):
        return None
    return {k: v for k, v in counts.items()
            if isinstance(v, int | float) and not isinstance(v, bool)}


def _timing_and_lines_cell(run: RunData) -> str:
    """The run's timing, and what the GNSS serial line delivered when the rig has one:
    losses (overrun, dropped: the DUT read too slowly; late: the bench) are flagged."""
    cell = _timing_cell(run)
    counts = gnss_epochs(run)
    if counts is None:
        return cell
    parts = [f"{counts.get('written', 0):.0f} written"]
    parts += [f"{counts[k]:.0f} {k}" for k in ("overrun", "dropped", "late") if counts.get(k)]
    lost = any(counts.get(k) for k in ("overrun", "dropped"))
    after, queue = counts.get("bytes_after_loss"), counts.get("line_queue_bytes")
    # a port nobody reads still takes up to a line-discipline queue's worth after its first
    # loss (the kernel's own buffering: plant_emulators/sowing_depth/gnss_serial.py, which
    # records that bound); records from before the byte count say only how many epochs got
    # through after it
    not_read = (after <= queue if after is not None and queue is not None
                else not counts.get("written_after_loss"))
    flag = ""
    if lost and not_read:
        first = counts.get("first_loss_s")
        since = f" after {first:g} s" if first is not None else ""
        parts.append(f"the DUT did not read the port{since}")
        flag = " " + badge("info", "PORT NOT READ")
    elif lost:
        flag = " " + badge("marginal", "EPOCHS LOST")
    return (f'{cell}<br><span class="small gnss-epochs">GNSS epochs: '
            f'{esc(", ".join(parts))}</span>{flag}')


def _counts_cell(run: RunData) -> str:
    counts = Counter(m.status for m in run.measurements)
    return ", ".join(f"{n} {s}" for s, n in sorted(counts.items(),
                                                   key=lambda kv: STATUS_ORDER[kv[0]])) or DASH


def runs_section(runs: list[RunData]) -> str:
    if not runs:
        return '<section id="runs"><h2>Runs</h2>' + note("the record lists no runs") + "</section>"
    rows = []
    for run in runs:
        arts = " ".join(link(f"{run.ref.dir}/{name}", name) for name in run.artifacts) or (
            '<span class="note">directory missing</span>')
        first = f'<span id="{esc(run.anchor)}"></span>{link(run.ref.dir, run.ref.dir)}'
        verdict = badge(run.result) if run.result else DASH
        rows.append(row([first, esc(run.scenario) or DASH, verdict,
                         esc(fmt_seconds(run.ref.sim_s)), esc(fmt_seconds(run.ref.wall_s)),
                         _timing_and_lines_cell(run), esc(_counts_cell(run)), arts],
                        f"r-{run.result or 'unknown'}"))
    headers = ("run", "scenario", "result", "simulated", "wall", "timing", "measurements",
               "artifacts")
    return f"""
<section id="runs">
  <h2>Runs</h2>
  <p class="small">Result: the worst outcome of the run's measurements, or the run's own
  verdict when it did not complete. Links are relative to this report: keep it in its
  qualification directory.
  Replay a bus log with <code>python -m can.player RUN/bus.log</code>; load traces with
  <code>hil.record.load_traces</code>. GNSS epochs (sowing-depth rig): written whole, overrun
  (written in part: the DUT read a truncated sentence), dropped (none of it written), both
  because the DUT read its serial port too slowly (EPOCHS LOST), as behind a real receiver's
  UART, or stopped reading it (PORT NOT READ: nothing got through after the first loss; a
  DUT that does not use the GNSS); late: the bench itself missed the epoch.</p>
  {table(headers, rows, "runs")}
</section>"""


def tests_section(qual: QualRecord) -> str:
    if not qual.tests:
        return ('<section id="tests"><h2>Tests</h2>' + note("the record lists no tests")
                + "</section>")
    counts = Counter(t.outcome or "unknown" for t in qual.tests)
    summary = ", ".join(f"{n} {o}" for o, n in sorted(counts.items()))
    rows = []
    for t in qual.tests:
        # the tail: pytest puts the exception (the line that says why) last
        message = ("…" if len(t.message) > MAX_MESSAGE else "") + t.message[-MAX_MESSAGE:]
        rows.append(row([f"<code>{esc(t.nodeid)}</code>", badge(t.outcome or "unknown"),
                         esc(fmt_seconds(t.duration_s)), pre(message) if message else ""],
                        f"t-{t.outcome or 'unknown'}"))
    return f"""
<section id="tests">
  <h2>Tests</h2>
  <p class="small">{len(qual.tests)} tests: {esc(summary)} (as in <code>junit.xml</code>).</p>
  {table(("test", "outcome", "duration", "message"), rows, "tests")}
</section>"""


def _run_error(run: RunData) -> str:
    rec = run.record
    dut = rec.get("dut") if isinstance(rec.get("dut"), dict) else {}
    parts = [f"<h3>run {link(run.ref.dir, run.ref.dir)} · {esc(run.scenario)} · "
             f"{badge(run.verdict or 'error')}</h3>"]
    if run.error:
        parts.append(pre(run.error))
    for key in ("failure", "exit"):
        if dut.get(key):
            parts.append(f"<p><b>DUT {esc(key)}:</b> {esc(dut[key])}</p>")
    for key, title in (("stderr_tail", "DUT stderr (tail)"), ("stdout_tail", "DUT stdout (tail)")):
        if dut.get(key):
            parts.append(f"<p><b>{title}</b></p>" + pre(str(dut[key])))
    if rec.get("traceback"):
        parts.append("<details><summary>traceback (tail)</summary>"
                     + pre(str(rec["traceback"])[-2000:]) + "</details>")
    if len(parts) == 1:
        parts.append(note("the run's record.json says nothing more"))
    return "\n".join(parts)


def errors_section(qual: QualRecord, runs: list[RunData]) -> str:
    """Empty when nothing errored."""
    blocks = []
    if qual.error:
        blocks.append("<h3>qualification</h3>" + pre(qual.error))
    for run in runs:
        dut = run.record.get("dut")
        errored = (run.verdict in ("error", "aborted") or run.error
                   or (isinstance(dut, dict) and dut.get("failure")))
        if errored:
            blocks.append(_run_error(run))
    for t in qual.tests:
        if t.outcome == "error":
            blocks.append(f"<h3>test <code>{esc(t.nodeid)}</code> {badge('error')}</h3>"
                          + (pre(t.message) if t.message else ""))
    if not blocks:
        return ""
    return '<section id="errors"><h2>Errors</h2>\n' + "\n".join(blocks) + "\n</section>"
