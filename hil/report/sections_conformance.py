"""The "Bus conformance" section: per message of the DUT, what its databases declare against
what the runs measured, and the outcome over every run; then the node-level checks (undeclared
frames, heartbeat, boot-up, bus share, SYNC latency). Built from the ``bus.*`` measurements of
the record and each run's ``conformance.json`` (:mod:`hil.conformance`)."""

from __future__ import annotations

import json
from collections import defaultdict
from typing import Any

from hil.limits import is_conformance
from hil.report.markup import DASH, badge, esc, fmt_num, note, row, table
from hil.report.record import STATUS_ORDER, MeasurementRow, QualRecord
from hil.report.rundata import RunData

DETAIL_FILE = "conformance.json"
MESSAGE_HEADERS = ("message", "id", "declared", "measured", "runs", "outcome")
CHECK_HEADERS = ("check", "limit", "measured (over runs)", "runs", "outcome")
#: node-level checks in the order shown: measurement name → label
CHECKS = (("bus.undeclared_frames", "undeclared frames"),
          ("bus.heartbeat.period", "heartbeat period, off declared"),
          ("bus.heartbeat.max_interval", "longest heartbeat interval"),
          ("bus.bootup.frames_before", "frames before boot-up"),
          ("bus.bootup.unexpected", "boot-ups not one per power-up"),
          ("bus.share", "share of the bit rate"),
          ("bus.sync_latency.p50", "SYNC → command, median"),
          ("bus.sync_latency.p99", "SYNC → command, 99th percentile"),
          ("bus.sync_latency.max", "SYNC → command, longest"))


def _worst(statuses: list[str]) -> str:
    return min(statuses, key=lambda s: STATUS_ORDER.get(s, 1)) if statuses else "info"


def _details(runs: list[RunData]) -> list[dict[str, Any]]:
    out = []
    for run in runs:
        path = run.path / DETAIL_FILE
        try:
            out.append(json.loads(path.read_text()))
        except (OSError, ValueError):
            continue
    return out


def _span(values: list[float], unit: str = "") -> str:
    finite = [v for v in values if isinstance(v, int | float)]
    if not finite:
        return DASH
    lo, hi = min(finite), max(finite)
    text = fmt_num(lo) if lo == hi else f"{fmt_num(lo)} … {fmt_num(hi)}"
    return f"{text} {unit}".strip()


def _message_rows(details: list[dict[str, Any]],
                  by_message: dict[str, list[MeasurementRow]]) -> list[str]:
    merged: dict[tuple[str, str], dict[str, Any]] = {}
    for detail in details:
        heartbeat = detail.get("heartbeat") or {}
        for m in detail.get("messages", []):
            if not m.get("frames"):
                continue
            if m["id"] == heartbeat.get("id"):     # its intervals are the heartbeat check's
                m = {**m, **{k: heartbeat.get(k) for k in ("median_ms", "min_ms", "max_ms")}}
            entry = merged.setdefault((m["id"], m["message"]), {
                "declared": m, "dlc_seen": set(), "medians": [], "mins": [], "maxes": [],
                "runs": 0})
            entry["runs"] += 1
            entry["dlc_seen"].update(m.get("dlc_seen", []))
            for key, into in (("median_ms", "medians"), ("min_ms", "mins"),
                              ("max_ms", "maxes")):
                if isinstance(m.get(key), int | float):
                    entry[into].append(m[key])
    rows = []
    for (can_id, name), entry in sorted(merged.items()):
        d = entry["declared"]
        declared = f"DLC {d['dlc_declared']}"
        if d.get("cycle_declared_ms"):
            declared += f", every {fmt_num(d['cycle_declared_ms'])} ms ({d['cycle_source']})"
        else:
            declared += ", event"
        declared = esc(declared) + f'<div class="small">{esc(d.get("source", ""))}</div>'
        if d.get("note"):
            declared += f'<div class="small">{esc(d["note"])}</div>'
        measured = "DLC " + ", ".join(str(n) for n in sorted(entry["dlc_seen"]))
        if entry["medians"]:
            measured += (f", median {_span(entry['medians'], 'ms')}, intervals "
                         f"{fmt_num(min(entry['mins']))} … {fmt_num(max(entry['maxes']))} ms")
        statuses = [m.status for m in by_message.get(name, [])]
        rows.append(row([esc(name), f"<code>{esc(can_id)}</code>", declared, esc(measured),
                         str(entry["runs"]), badge(_worst(statuses))],
                        f"m-{_worst(statuses)}"))
    return rows


def _check_rows(measurements: list[MeasurementRow]) -> list[str]:
    by_name: dict[str, list[MeasurementRow]] = defaultdict(list)
    for m in measurements:
        by_name[m.name].append(m)
    rows = []
    for name, label in CHECKS:
        ms = by_name.get(name)
        if not ms:
            continue
        lows = {m.low for m in ms}
        highs = {m.high for m in ms}
        limit = " · ".join(part for part in (
            f"≥ {_span([v for v in lows if v is not None])}" if lows - {None} else "",
            f"≤ {_span([v for v in highs if v is not None])}" if highs - {None} else "")
            if part) or "recorded"
        worst = _worst([m.status for m in ms])
        measured = _span([m.value for m in ms], ms[0].unit)
        bad = [m for m in ms if m.status in ("fail", "error") and m.note]
        if bad:
            measured = esc(measured) + f'<div class="small">{esc(bad[0].note)}</div>'
        else:
            measured = esc(measured)
        rows.append(row([f"{esc(label)}<div class='small'><code>{esc(name)}</code></div>",
                         esc(f"{limit} {ms[0].unit}" if limit != "recorded" else limit),
                         measured, str(len(ms)), badge(worst)], f"m-{worst}"))
    return rows


def conformance_section(qual: QualRecord, runs: list[RunData]) -> str:
    """The section's HTML ("" when the record holds no conformance measurement)."""
    bus = [m for m in qual.measurements if is_conformance(m.name)]
    if not bus:
        return ""
    by_message: dict[str, list[MeasurementRow]] = defaultdict(list)
    for m in bus:
        if "message" in m.conditions:
            by_message[str(m.conditions["message"])].append(m)
    details = _details(runs)
    messages = _message_rows(details, by_message)
    body = (table(MESSAGE_HEADERS, messages, "measurements") if messages
            else note("no run left a conformance.json with per-message detail"))
    body += table(CHECK_HEADERS, _check_rows(bus), "measurements")
    node = next((d.get("node") for d in details if d.get("node")), "")
    databases = sorted({db for d in details for db in d.get("databases", [])})
    where = (f"The DUT's node <code>{esc(node)}</code>; databases: "
             + ", ".join(f"<code>{esc(db.rsplit('/', 1)[-1])}</code>" for db in databases)
             + ". " if node else "")
    return f"""
<section id="conformance">
  <h2>Bus conformance</h2>
  <p class="small">{where}Per message the DUT sent: what its databases declare and what the
  runs measured; the outcome is the worst over every run (data length, cycle time). Then the
  node's checks. Definitions and default limits: docs/guide/bus-conformance.md.</p>
  {body}
</section>"""
