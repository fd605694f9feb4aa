"""The plot sections: step responses, field runs, per-condition charts, other runs, timing."""

from __future__ import annotations

from hil.report.markup import badge, esc, figure, fmt_num, note
from hil.report.plots_runs import RunPlot, classify, plot_run
from hil.report.plots_summary import by_name, condition_chart, timing_histogram
from hil.report.record import QualRecord
from hil.report.rundata import RunData

KIND_TITLES = (
    ("step", "Step responses",
     "Setpoint (dashed), sensed and true signal with the ±5 % band around the setpoint; "
     "vertical lines mark the measured response time (and its limit) after each step."),
    ("field", "Field runs against truth",
     "The main signal with what the DUT sensed against the true plant signal, and the "
     "truth (delivered mass, seed depth along the row)."),
    ("other", "Other runs",
     "The main signal of every other run; dotted lines mark injected faults."),
)


def _caption(plot: RunPlot) -> str:
    run = plot.run
    head = (f'<a href="#{esc(run.anchor)}">{esc(run.ref.dir)}</a> · {esc(run.scenario)} '
            f"{badge(run.result) if run.result else ''}")
    items = "".join(
        f"<li><code>{esc(m.name)}</code> {esc(m.conditions_label)} = "
        + ("<i>no value</i>" if m.value is None else
           f"<b>{esc(fmt_num(m.value))}</b> {esc(m.unit)}")
        + f" {badge(m.status)}</li>"
        for m in run.measurements)
    return head + (f'<ul class="mlist">{items}</ul>' if items else "")


def _run_block(plot: RunPlot) -> str:
    notes = "".join(note(n) for n in [*plot.run.notes, *plot.notes])
    if plot.image is None:
        return (f'<div class="figure-missing"><div class="figcap">{_caption(plot)}</div>'
                f"{notes or note('no plot')}</div>")
    return f'<div class="plot">{figure(plot.image, _caption(plot))}{notes}</div>'


def _safe_plot(run: RunData) -> RunPlot:
    """A run whose data breaks the plotting (arrays of different lengths, say) gets a note:
    one bad run must not cost the report."""
    try:
        return plot_run(run)
    except Exception as exc:
        return RunPlot(run=run, kind=classify(run),
                       notes=[f"{run.ref.dir}: plot failed ({type(exc).__name__}: {exc})"])


def run_plot_sections(runs: list[RunData]) -> dict[str, str]:
    """kind (step, field, other) → its section; kinds without runs are left out."""
    plots = [_safe_plot(run) for run in runs]
    out = {}
    for kind, title, blurb in KIND_TITLES:
        chosen = [p for p in plots if p.kind == kind]
        if not chosen:
            continue
        blocks = "\n".join(_run_block(p) for p in chosen)
        out[kind] = (f'<section id="plots-{kind}"><h2>{esc(title)}</h2>'
                     f'<p class="small">{esc(blurb)}</p><div class="grid">{blocks}</div>'
                     f"</section>")
    return out


def condition_section(qual: QualRecord) -> str:
    charts = by_name(qual.measurements)
    if not charts:
        return ""
    blocks = []
    for name, ms in charts:
        try:
            blocks.append(f'<div class="plot">{figure(condition_chart(name, ms))}</div>')
        except Exception as exc:  # odd values must not cost the report
            blocks.append(note(f"{name}: chart failed ({type(exc).__name__}: {exc})"))
    figures = "\n".join(blocks)
    return (f'<section id="per-condition"><h2>Measurements per condition</h2>'
            f'<p class="small">Every measurement taken under more than one condition. Dots: '
            f'green pass, amber marginal, red fail, a cross "error" no value; dashed red: the '
            f'limit; shaded green: the values that pass. The value axis spans the values and '
            f'their limits, so a value is seen at the scale of its margin.</p>'
            f'<div class="grid">{figures}</div></section>')


def _timing_stats(timing: dict[str, object]) -> str:
    def us(key: str) -> str:
        v = timing.get(key)
        return f"{v * 1e6:.1f} µs" if isinstance(v, int | float) else "—"

    valid = timing.get("valid", True)
    raw = timing.get("invalid_reasons") or []
    reasons = raw if isinstance(raw, list) else [raw]
    verdict = badge("pass", "WITHIN BOUNDS") if valid else badge("invalid-bench")
    items = (f"p50 {us('lateness_p50_s')} · p99 {us('lateness_p99_s')} · "
             f"p99.9 {us('lateness_p999_s')} · max {us('lateness_max_s')} · "
             f"misses {esc(timing.get('misses', '—'))} · stalls {esc(timing.get('stalls', '—'))}"
             f" · ticks {esc(timing.get('ticks', '—'))} · scheduler "
             f"{esc(timing.get('scheduler', '—'))}")
    why = "".join(f"<li>{esc(r)}</li>" for r in reasons)
    return f"<p>{verdict} {items}</p>" + (f"<ul>{why}</ul>" if why else "")


def timing_section(qual: QualRecord) -> str:
    timing = qual.timing
    head = '<section id="timing"><h2>Bench timing</h2>'
    if not timing:
        return head + note("the record holds no timing health") + "</section>"
    mode = timing.get("mode")
    if mode == "lockstep":
        return (head + '<p class="lockstep">lockstep: virtual time, no lateness. The plant '
                "waited for the DUT every control period; timing says nothing about the "
                "bench here.</p></section>")
    body = _timing_stats(timing)
    try:
        image = timing_histogram(timing)
    except Exception as exc:  # a malformed histogram must not cost the report
        body += note(f"timing histogram failed ({type(exc).__name__}: {exc})")
    else:
        body += (figure(image) if image else note(
            "no lateness histogram in the record (histogram_edges_s / histogram_counts)"))
    return head + f'<p class="small">Mode {esc(mode)}: the worst run.</p>' + body + "</section>"
