"""``hil gate``: a qualification record in, a verdict for the controller build out.

    hil gate qual/record.json
    hil gate qual/record.json --baseline ci/baselines/DUT.json --tolerance ci/tolerances.toml
    hil gate qual/record.json --baseline ci/baselines/DUT.json --update-baseline

Exit status: 0 pass; 1 fail (a measurement outside its limits or not computed, a regression
beyond tolerance, a baseline measurement missing; a campaign whose exact upper bound is below
its required pass probability); 2 no verdict (the record is ``invalid-bench``, ``error`` or
incomplete) or bad input (unreadable record, baseline or tolerance file; a baseline of another
DUT); 3 a campaign that is inconclusive on its requirement (neither bound crosses it).
"""

from __future__ import annotations

import argparse
import os
import sys
from datetime import UTC, datetime
from pathlib import Path

from hil.cli.args import check_writable_file
from hil.errors import ConfigError
from hil.gate import (
    DEFAULT_TOLERANCES,
    Verdict,
    baseline_from_record,
    check_baseline_dut,
    compare,
    load_baseline,
    load_record,
    load_tolerances,
    render_markdown,
    render_text,
    write_baseline,
)
from hil.gate.completeness import incomplete_reason
from hil.gate.jsonfile import read_json
from hil.validation import help_with_range, option_type


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    gate = subparsers.add_parser(
        "gate", help="turn a qualification record into a pass/fail verdict for a build",
        description="Judge a qualification record (record.json of 'hil qualify'): every "
                    "measurement against its limits and, with --baseline, against a stored "
                    "baseline with tolerance bands; or a campaign record (campaign.json of "
                    "'hil campaign'): its pass probability against the profile's "
                    "requirement by exact binomial bounds and, with --baseline, the shift of "
                    "every measurement's distribution. Exit 0 pass, 1 fail, 2 no verdict "
                    "(invalid bench, qualification error, incomplete record) or bad input, "
                    "3 campaign inconclusive.")
    gate.add_argument("record", metavar="RECORD.json",
                      help="the qualification record, or a campaign.json of 'hil campaign' "
                           "(then --baseline is a compact campaign baseline, which "
                           "--update-baseline writes, or another campaign.json)")
    gate.add_argument("--baseline", metavar="BASELINE.json",
                      help="compare against this baseline (and write it with --update-baseline)")
    gate.add_argument("--tolerance", metavar="FILE.toml",
                      help="tolerance bands per measurement name (default: 5 %% of the "
                           "baseline value for every measurement)")
    gate.add_argument("--summary", metavar="FILE.md",
                      help="write the Markdown summary here (default: append it to "
                           "$GITHUB_STEP_SUMMARY when that is set)")
    gate.add_argument("--allow-regressions", action="store_true",
                      help="report regressions as warnings instead of failing")
    gate.add_argument("--update-baseline", action="store_true",
                      help="write the record as the new baseline to --baseline PATH (only "
                           "from a passing record unless --force); the comparison with the "
                           "old baseline is still shown")
    gate.add_argument("--force", action="store_true",
                      help="write a baseline from a record that did not pass; compare with "
                           "or overwrite a baseline of another DUT")
    gate.add_argument("--shift-fraction", type=option_type("gate --shift-fraction"),
                      default=0.25,  # campaign (issue 15)
                      help=help_with_range("gate --shift-fraction",
                                           "campaign records only: a mean shift is a "
                                           "regression beyond this fraction of the "
                                           "tolerance band (default: 0.25)"))
    gate.add_argument("--rig", metavar="FILE", default=None,
                      help="the rig file of a rig of your own (its measurements' names, for "
                           "--tolerance)")
    gate.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from hil.campaign.record import is_campaign
    from hil.ownrig.cli_support import register_option_rig

    register_option_rig(args.rig)       # a rig of your own: its measurements' names known

    if args.update_baseline and args.baseline:
        check_writable_file(args.baseline, "--baseline", make_dirs=True)
    if args.summary:
        check_writable_file(args.summary, "--summary")
    # one rule for every record kind, before anything is judged: a record that did not
    # finish has no verdict (exit 2, saying why), with or without a baseline
    campaign = is_campaign(args.record)
    source = Path(args.record)
    if campaign and source.is_dir():
        source = source / "campaign.json"
    what = "campaign record" if campaign else "qualification record"
    # (a campaign that stopped early is complete when its stopping rule decided; imported
    # here: it needs scipy, which no other hil command should pay for)
    if campaign:
        from hil.gate.campaign_requirement import campaign_incomplete_reason as judge_complete
    else:
        judge_complete = incomplete_reason
    incomplete = judge_complete(read_json(source, what), path=str(source))
    if incomplete:
        print(f"hil: error: {incomplete}", file=sys.stderr)
        return 2
    if campaign:  # a campaign record (issue 15): compared by distribution
        from hil.gate.campaign_cli import run_campaign_gate

        return run_campaign_gate(args)
    record = load_record(args.record)
    tolerances = load_tolerances(args.tolerance) if args.tolerance else DEFAULT_TOLERANCES
    if args.update_baseline and not args.baseline:
        raise ConfigError("--update-baseline needs --baseline PATH (where to write it)",
                          key="--baseline")
    baseline, notes = None, []
    if args.baseline and (Path(args.baseline).exists() or not args.update_baseline):
        baseline = load_baseline(args.baseline)
        notes = check_baseline_dut(baseline, record, force=args.force)
    result = compare(record, baseline, tolerances, allow_regressions=args.allow_regressions,
                     accept_changes=args.update_baseline, notes=tuple(notes))
    written = ""
    if args.update_baseline:
        if not record.measurements:
            raise ConfigError("the record has no measurements: no baseline to write",
                              path=record.path, key="measurements")
        if result.verdict is Verdict.PASS or args.force:
            write_baseline(baseline_from_record(record, created_at=datetime.now(UTC),
                                                path=args.baseline), args.baseline)
            written = args.baseline
        else:
            print(f"hil: baseline not written: the record did not pass (gate verdict "
                  f"{result.verdict.value}); --force stores it anyway", file=sys.stderr)
    _write_summary(render_markdown(result, baseline_written=written), args.summary)
    print(render_text(result, baseline_written=written))
    return result.exit_code


def _write_summary(markdown: str, path: str | None) -> None:
    target, mode = (path, "w") if path else (os.environ.get("GITHUB_STEP_SUMMARY"), "a")
    if not target:
        return
    try:
        with open(target, mode, encoding="utf-8") as fh:
            fh.write(markdown + "\n")
    except OSError as exc:
        raise ConfigError(f"cannot write the summary: {exc.strerror or exc}",
                          path=target) from exc
