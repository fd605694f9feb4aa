"""``hil gate CAMPAIGN.json``: the campaign branch of the gate command (see
:mod:`hil.gate.campaign`); the baseline is another campaign record."""

from __future__ import annotations

import argparse
import shutil
import sys

from hil.campaign.record import load_campaign
from hil.errors import ConfigError
from hil.gate.campaign import compare_campaigns, render_campaign_text
from hil.gate.tolerance import DEFAULT_TOLERANCES, load_tolerances


def run_campaign_gate(args: argparse.Namespace) -> int:
    """Gate a campaign record; ``--update-baseline`` copies it to ``--baseline``."""
    from pathlib import Path

    record = load_campaign(args.record)
    tolerances = load_tolerances(args.tolerance) if args.tolerance else DEFAULT_TOLERANCES
    if args.update_baseline and not args.baseline:
        raise ConfigError("--update-baseline needs --baseline PATH (where to write it)",
                          key="--baseline")
    baseline = None
    if args.baseline and (Path(args.baseline).exists() or not args.update_baseline):
        baseline = load_campaign(args.baseline)
    result = compare_campaigns(record, baseline, tolerances,
                               allow_regressions=args.allow_regressions,
                               shift_fraction=args.shift_fraction)
    text = render_campaign_text(result, record)
    if args.update_baseline:
        if result.verdict == "pass" or args.force:
            shutil.copyfile(record["_path"], args.baseline)
            text += f"\nbaseline written: {args.baseline}"
        else:
            print("hil: baseline not written: the campaign did not pass the gate; --force "
                  "stores it anyway", file=sys.stderr)
    if args.summary:
        try:
            Path(args.summary).write_text("```\n" + text + "\n```\n", encoding="utf-8")
        except OSError as exc:
            raise ConfigError(f"cannot write the summary: {exc}", path=args.summary) from exc
    print(text)
    return result.exit_code
