"""The whole page: one self-contained ``report.html`` next to the qualification record."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

from hil import __version__
from hil.report.markup import esc
from hil.report.record import QualRecord, ReportError, load_qualification
from hil.report.rundata import RunData, load_runs
from hil.report.sections_conformance import conformance_section
from hil.report.sections_field import field_section
from hil.report.sections_head import VERDICT_WORDS, header, identity_section, verdict_section
from hil.report.sections_plots import condition_section, run_plot_sections, timing_section
from hil.report.sections_tables import (
    errors_section,
    measurements_section,
    runs_section,
    tests_section,
)
from hil.report.sections_vt import vt_section
from hil.report.style import CSS

REPORT_NAME = "report.html"

# the verdict and the measurement table fill the first screenful (1366x768); who was tested
# on what bench follows them (the verdict banner names the DUT, its version and build)
_NAV = (("verdict", "Verdict"), ("measurements", "Measurements"),
        ("conformance", "Bus conformance"), ("identity", "Device and bench"),
        ("plots-step", "Step responses"),
        ("plots-field", "Field runs"), ("field-maps", "Field maps"),
        ("vt-screens", "Operator's screens"),
        ("per-condition", "Per condition"),
        ("plots-other", "Other runs"), ("timing", "Timing"), ("runs", "Runs"),
        ("tests", "Tests"), ("errors", "Errors"))

_SIGNOFF = """
<section class="signoff" id="signoff">
  <div>Reviewed by (name)</div><div>Date</div><div>Signature</div>
</section>"""


def render(qual: QualRecord, runs: list[RunData]) -> str:
    errors = errors_section(qual, runs)
    plots = run_plot_sections(runs)
    sections = {
        "verdict": verdict_section(qual, runs, has_errors=bool(errors)),
        "measurements": measurements_section(qual, runs),
        "conformance": conformance_section(qual, runs),
        "identity": identity_section(qual, runs),
        "plots-step": plots.get("step", ""),
        "plots-field": plots.get("field", ""),
        "field-maps": field_section(qual, runs),
        "vt-screens": vt_section(qual, runs),
        "per-condition": condition_section(qual),
        "plots-other": plots.get("other", ""),
        "timing": timing_section(qual),
        "runs": runs_section(runs),
        "tests": tests_section(qual),
        "errors": errors,
    }
    nav = " ".join(f'<a href="#{key}">{esc(label)}</a>' for key, label in _NAV
                   if sections.get(key))
    word = VERDICT_WORDS.get(qual.verdict, qual.verdict.upper())
    title = f"{word} · {qual.dut.get('name') or 'DUT'} {qual.dut.get('version') or ''}".strip()
    now = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    body = "\n".join(s for s in sections.values() if s)
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{esc(title)} · qualification report</title>
<style>{CSS}</style>
</head>
<body>
{header(qual)}
<nav>{nav}</nav>
{body}
{_SIGNOFF}
<footer>Written by agrihil {esc(__version__)} at {esc(now)} from
<code>record.json</code> ({esc(qual.schema)}); regenerate with
<code>hil report {esc(qual.path.parent.name or '.')}</code>.</footer>
</body>
</html>
"""


def write_html(qual_dir: Path) -> Path:
    """Read ``qual_dir/record.json`` and its runs; write ``qual_dir/report.html``.

    Raises :class:`~hil.report.record.ReportError` (naming the file) when the record is
    missing or invalid; anything wrong with a run becomes a note on the page.
    """
    qual_dir = Path(qual_dir)
    qual = load_qualification(qual_dir)
    runs = load_runs(qual)
    out = qual_dir / REPORT_NAME
    tmp = out.with_suffix(".html.tmp")
    try:
        tmp.write_text(render(qual, runs), encoding="utf-8")
        tmp.replace(out)
    except OSError as exc:
        raise ReportError(f"{out}: cannot write the report: {exc}") from None
    return out
