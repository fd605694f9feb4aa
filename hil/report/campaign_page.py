"""The campaign's ``report.html``: one self-contained page next to ``campaign.json``.

Same style as the qualification report (:mod:`hil.report.style`): the verdict first, then per
measurement the distribution against its limits (histogram and ECDF), mean, SD, min/max, the
pass rate with its exact 95 % interval and the worst samples linked to their full reruns.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

from hil import __version__
from hil.campaign.record import load_campaign
from hil.report.campaign_plots import distribution_image
from hil.report.markup import esc
from hil.report.style import CSS

REPORT_NAME = "report.html"
_VERDICT_CSS = {"pass": "pass", "fail": "fail", "inconclusive": "marginal", "error": "error"}


def _fmt(x: Any, digits: int = 4) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return esc(str(x))


def _verdict(doc: dict[str, Any]) -> str:
    s = doc["summary"]
    cls = _VERDICT_CSS.get(s["verdict"], "error")
    req = doc.get("requirement")
    need = (f"required: pass probability {req['pass_probability']:g} at "
            f"{req['confidence']:.0%} confidence" if req else
            "no requirement in the profile: every sample must pass")
    ci = s["ci95"]
    rate = f"{s['pass_rate']:.2%}" if s["pass_rate"] is not None else "-"
    return f"""
<section id="verdict"><div class="verdict" style="--vc: var(--{cls}); --vbg: #fafafa">
<div class="verdict-word">{esc(s['verdict'].upper())}</div>
<div><p><b>{esc(s['reason'])}</b></p>
<p>{s['passed']} of {s['judged']} samples passed ({rate}; exact 95 % interval
{ci[0]:.4f} to {ci[1]:.4f}); demonstrated pass probability {s['demonstrated_pass_probability']:.4f}
at {s['confidence']:.0%} confidence; {s['errors']} error samples
(not counted){'; samples needed: ' + str(s['samples_needed']) if s.get('samples_needed') else ''}.
</p><p class="small">{esc(need)}. Status: {esc(doc['status'])}
({len(doc['samples'])} of {doc['samples_requested']} samples).</p></div></div></section>"""


def _identity(doc: dict[str, Any]) -> str:
    dut = doc["dut"]
    disp = doc.get("dispersion")
    rows = [("DUT", f"{dut.get('name')} {dut.get('version')} ({dut.get('kind')})"),
            ("Profile", dut.get("profile")), ("Rig", doc["rig"]["name"]),
            ("Bus / clock", f"{doc['bus']} / {doc['clock']}"), ("Suites", doc["suites"]),
            ("Seeds", f"{doc['seed']} .. {doc['seed'] + doc['samples_requested'] - 1}"),
            ("Engine", ", ".join(f"{k}: {v}" for k, v in doc["engine"].items())),
            ("Wall time", f"{doc['wall_s']:.0f} s")]
    body = "".join(f"<tr><th>{esc(k)}</th><td>{esc(str(v))}</td></tr>" for k, v in rows)
    disp_html = "<p>No dispersion: nominal rig parameters, the seeds alone vary.</p>"
    if disp:
        items = "".join(
            f"<tr><td><code>{esc(k)}</code></td><td>{esc(p['dist'])}("
            + esc(", ".join(f"{a}={v:g}" for a, v in p.items() if a not in ('dist', 'source')))
            + f")</td><td class='small'>{esc(p['source'])}</td></tr>"
            for k, p in disp["parameters"].items())
        disp_html = (f"<h3>Dispersion: <code>{esc(disp['path'])}</code></h3><table>"
                     f"<tr><th>parameter</th><th>distribution</th><th>source</th></tr>{items}"
                     "</table>")
    return (f'<section id="identity"><h2>Device and campaign</h2><table>{body}</table>'
            f"{disp_html}</section>")


def _sample_link(doc: dict[str, Any], index: int) -> str:
    rerun = next((r for r in doc["reruns"] if r["index"] == index), None)
    if rerun is None:
        return f"#{index}"
    return f'<a href="{esc(rerun["report"])}">#{index}</a>'


def _measurements(doc: dict[str, Any]) -> str:
    values: dict[str, list[tuple[int, float | None]]] = {}
    from hil.gate.keys import measurement_key

    for s in doc["samples"]:
        for m in s["measurements"]:
            values.setdefault(measurement_key(m["name"], m.get("conditions") or {}), []).append(
                (s["index"], m.get("value")))
    parts = ['<section id="measurements"><h2>Measurements</h2>'
             '<table><tr><th>measurement</th><th>limits</th><th>n</th><th>mean</th><th>SD</th>'
             '<th>min</th><th>max</th><th>pass rate (95 % CI)</th><th>worst samples</th></tr>']
    for key, st in doc["measurements"].items():
        lim = f"{_fmt(st['low'])} .. {_fmt(st['high'])} {esc(st['unit'] or '')}"
        cls = "fail" if st["failed"] else "pass"
        worst = " ".join(_sample_link(doc, i) for i in st["worst"])
        rate = f"{st['pass_rate']:.1%}" if st["pass_rate"] is not None else "-"
        parts.append(
            f'<tr><td><a href="#m-{esc(key)}">{esc(key)}</a></td><td>{lim}</td><td>{st["n"]}'
            f"</td><td>{_fmt(st['mean'])}</td><td>{_fmt(st['sd'], 3)}</td>"
            f"<td>{_fmt(st['min'])}</td><td>{_fmt(st['max'])}</td>"
            f'<td class="{cls}">{rate} ({st["ci95"][0]:.3f}-{st["ci95"][1]:.3f})</td>'
            f"<td>{worst}</td></tr>")
    parts.append("</table>")
    for key, st in doc["measurements"].items():
        pts = [v for _, v in values.get(key, []) if v is not None]
        img = distribution_image(key, pts, low=st["low"], high=st["high"], unit=st["unit"])
        parts.append(f'<h3 id="m-{esc(key)}">{esc(key)}</h3>'
                     + (f'<img src="{img.uri}" alt="{esc(img.alt)}">' if img else
                        "<p>no values</p>"))
    parts.append("</section>")
    return "".join(parts)


def _reruns(doc: dict[str, Any]) -> str:
    if not doc["reruns"]:
        return ""
    rows = "".join(
        f"<tr><td>{_sample_link(doc, r['index'])}</td><td>{r['seed']}</td>"
        f"<td>{esc('; '.join(r['why']))}</td><td>{esc(r['verdict'])}</td>"
        f"<td>{_reproduced(r)}</td>"
        f"<td><code>{esc(r['command'])}</code></td></tr>" for r in doc["reruns"])
    return ('<section id="reruns"><h2>Failing and worst samples, rerun with full recording'
            '</h2><table><tr><th>sample</th><th>seed</th><th>why</th><th>verdict</th>'
            '<th>reproduced</th><th>reproduce with</th></tr>' + rows + "</table></section>")


def _errors(doc: dict[str, Any]) -> str:
    bad = [s for s in doc["samples"] if s["verdict"] not in ("pass", "fail")]
    if not bad:
        return ""
    rows = "".join(f"<tr><td>#{s['index']}</td><td>{s['seed']}</td><td>{esc(s['verdict'])}"
                   f"</td><td><pre>{esc(str(s.get('error')))}</pre></td></tr>" for s in bad)
    return ('<section id="errors"><h2>Error samples (not counted)</h2><table><tr><th>sample'
            '</th><th>seed</th><th>verdict</th><th>reason</th></tr>' + rows
            + "</table></section>")


def render(doc: dict[str, Any]) -> str:
    """The page of a campaign record."""
    now = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    title = f"{doc['summary']['verdict'].upper()} · campaign of {doc['dut'].get('name')}"
    body = _verdict(doc) + _identity(doc) + _measurements(doc) + _reruns(doc) + _errors(doc)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{esc(title)}</title><style>{CSS}
td.pass {{ color: var(--pass); }} td.fail {{ color: var(--fail); font-weight: 700; }}
table {{ border-collapse: collapse; }} td, th {{ border: 1px solid var(--line);
padding: 3px 6px; text-align: left; vertical-align: top; }}</style></head>
<body><h1>{esc(title)}</h1>
<nav><a href="#verdict">Verdict</a> <a href="#identity">Device and campaign</a>
<a href="#measurements">Measurements</a> <a href="#reruns">Reruns</a>
<a href="#errors">Errors</a></nav>
{body}
<footer>Written by agrihil {esc(__version__)} at {esc(now)} from <code>campaign.json</code>
({esc(doc['schema'])}).</footer></body></html>
"""


def write_campaign_html(out: Path) -> Path:
    """Read ``out/campaign.json``; write ``out/report.html``."""
    doc = load_campaign(out)
    path = Path(out) / REPORT_NAME
    tmp = path.with_suffix(".html.tmp")
    tmp.write_text(render(doc), encoding="utf-8")
    tmp.replace(path)
    return path


def _reproduced(rerun: dict[str, Any]) -> str:
    """A rerun's reproduction as a cell: yes, NO, or why the rerun could not say."""
    if rerun["reproduced"] is None:
        return f"<b>rerun failed</b>: {esc(str(rerun.get('error') or '?'))}"
    return "yes" if rerun["reproduced"] else "<b>NO</b>"
