"""``hil gate CAMPAIGN.json``: the campaign branch of the gate command (see
:mod:`hil.gate.campaign`); the baseline is a compact campaign baseline
(:mod:`hil.gate.campaign_baseline`, what ``--update-baseline`` writes) or another campaign
record."""

from __future__ import annotations

import argparse
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from hil.campaign.record import SCHEMA as CAMPAIGN_SCHEMA
from hil.campaign.record import load_campaign
from hil.errors import ConfigError
from hil.gate.campaign import compare_campaigns, render_campaign_text
from hil.gate.campaign_baseline import SCHEMA as COMPACT_SCHEMA
from hil.gate.campaign_baseline import compact_baseline, is_compact, load_compact
from hil.gate.campaign_requirement import campaign_incomplete_reason
from hil.gate.jsonfile import read_json, write_json
from hil.gate.tolerance import DEFAULT_TOLERANCES, load_tolerances


def load_campaign_baseline(path: str) -> dict[str, Any]:
    """A campaign baseline: compact (``agrihil.campaign-baseline/1``) or a whole campaign
    record; anything else is a :class:`ConfigError` naming the file."""
    doc = read_json(path, "campaign baseline")
    if is_compact(doc):
        return load_compact(doc, path=path)
    if isinstance(doc, dict) and doc.get("schema") == CAMPAIGN_SCHEMA:
        return load_campaign(path)
    found = doc.get("schema") if isinstance(doc, dict) else None
    raise ConfigError(f"not a campaign baseline (schema {found!r}, expected {COMPACT_SCHEMA} "
                      f"or {CAMPAIGN_SCHEMA})", path=path, key="schema")


def check_campaign_baseline(record: dict[str, Any], baseline: dict[str, Any], *, path: str,
                            force: bool) -> None:
    """Refuse a baseline that cannot be compared with ``record``: one that did not finish, or
    (unless ``force``) one of another rig or another DUT. Raises :class:`ConfigError` naming
    ``--baseline`` and both sides."""
    if not is_compact(baseline):
        incomplete = campaign_incomplete_reason(baseline, path=path)
        if incomplete:
            raise ConfigError(f"not a baseline: {incomplete}", key="--baseline")
    rig, base_rig = _rig(record), _rig(baseline)
    if rig != base_rig:      # other measurements, other limits: never comparable
        raise ConfigError(f"{path} is a campaign of the {base_rig} rig, the record one of the "
                          f"{rig} rig: compare campaigns of the same rig", key="--baseline")
    name, base_name = record["dut"].get("name"), baseline["dut"].get("name")
    if name != base_name and not force:
        raise ConfigError(f"{path} is a campaign of {base_name}, the record one of {name} "
                          f"(--force compares them anyway)", key="--baseline")


def _rig(doc: dict[str, Any]) -> str:
    rig = doc.get("rig")
    return str(rig.get("name") if isinstance(rig, dict) else rig)


def run_campaign_gate(args: argparse.Namespace) -> int:
    """Gate a campaign record; ``--update-baseline`` writes its compact baseline to
    ``--baseline`` (from a campaign that passed the gate or is inconclusive; a failing one
    only with ``--force``)."""
    record = load_campaign(args.record)
    tolerances = load_tolerances(args.tolerance) if args.tolerance else DEFAULT_TOLERANCES
    if args.update_baseline and not args.baseline:
        raise ConfigError("--update-baseline needs --baseline PATH (where to write it)",
                          key="--baseline")
    baseline = None
    if args.baseline and (Path(args.baseline).exists() or not args.update_baseline):
        baseline = load_campaign_baseline(args.baseline)
        check_campaign_baseline(record, baseline, path=args.baseline, force=args.force)
    result = compare_campaigns(record, baseline, tolerances,
                               allow_regressions=args.allow_regressions,
                               shift_fraction=args.shift_fraction)
    text = render_campaign_text(result, record)
    if args.update_baseline:
        # on its own verdict: a shift from the old baseline is what an update accepts
        if result.campaign_verdict in ("pass", "inconclusive") or args.force:
            compact = compact_baseline(record, created_at=datetime.now(UTC).isoformat(
                timespec="seconds"))
            write_json(args.baseline, compact)
            text += (f"\nbaseline written: {args.baseline} (compact, n = {compact['n']} "
                     f"judged samples)")
        else:
            print(f"hil: baseline not written: the campaign is {result.campaign_verdict}; "
                  f"--force stores it anyway", file=sys.stderr)
    if args.summary:
        try:
            Path(args.summary).write_text("```\n" + text + "\n```\n", encoding="utf-8")
        except OSError as exc:
            raise ConfigError(f"cannot write the summary: {exc}", path=args.summary) from exc
    print(text)
    return result.exit_code
