"""``hil campaign``: a Monte-Carlo campaign of the qualification suites (issue 15).

    hil campaign dut_profiles/fertilizer-piecewise-pid-firmware.toml --samples 300
    hil campaign PROFILE --samples 50 --bus inline --workers 2 --out camp
    hil campaign PROFILE --samples 300 --scheduler tcp://10.0.0.5:8786

Sample i runs the chosen suites at seed S+i with the rig parameters of the dispersion file
drawn for that seed (default: the rig's shipped ``dispersion.toml``; ``--dispersion none``:
nominal parameters, seeds only). Writes ``campaign.json``, ``samples.jsonl``, ``report.html``
and, under ``samples/NNNN/``, full qualifications of the failing and worst samples. With a
``[campaign]`` requirement in the profile the campaign stops as soon as its N-sample verdict
cannot change (``--no-early-stop``: run all N); ``--sequential`` runs Wald's SPRT the profile
states instead (:mod:`hil.campaign.decision`). Exit 0 when the campaign passes, 1 when it
fails, 3 when it is inconclusive, 2 on setup errors or when no sample completed.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from hil.cli.args import (
    add_bus_clock,
    check_bus_for_dut,
    check_bus_spec,
    check_keyword,
    check_launchable,
    prepare_out_dir,
)
from hil.cli.phases import phase
from hil.errors import ConfigError
from hil.limits import is_conformance
from hil.record.staging import Staging, is_storage_error, signals_held
from hil.validation import help_with_range, option_type

#: exit status by verdict; inconclusive (the samples neither demonstrate the requirement nor
#: rule it out) has its own, as in ``hil gate``
EXIT_BY_VERDICT = {"pass": 0, "fail": 1, "inconclusive": 3, "error": 2}
#: what a campaign writes into --out (moved in from its staging directory, the record last;
#: the names of hil.campaign.record, not imported here: that would import scipy for every
#: ``hil`` command)
RECORD_NAME = "campaign.json"
OUTPUTS = ("samples.jsonl", "samples", "report.html")
STAGING_PREFIX = ".campaign-"
#: the most samples rerun with full recording by default (--max-reruns)
DEFAULT_MAX_RERUNS = 10


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = subparsers.add_parser(
        "campaign", help="run the suites N times with dispersed rig parameters (Dask)",
        description="Monte-Carlo qualification: N samples of the chosen suites, sample i at "
                    "seed S+i with rig parameters drawn from a dispersion file, on a local "
                    "Dask cluster or an existing one; pass rate with an exact confidence "
                    "interval, per-measurement distributions, failing and worst samples "
                    "rerun with full recording. With the profile's [campaign] requirement "
                    "the campaign stops as soon as its verdict cannot change. Every option is "
                    "checked before any worker starts. Exit 0 pass, 1 fail, 3 inconclusive, "
                    "2 setup error or no sample completed.")
    p.add_argument("profile", help="DUT profile (TOML)")
    p.add_argument("--samples", type=option_type("campaign --samples"), required=True,
                   help=help_with_range("campaign --samples", "number of samples N"))
    add_bus_clock(p)
    p.add_argument("--suite", default="fast", help="comma-separated suites (default: fast)")
    p.add_argument("-k", dest="keyword", default=None,
                   help="pytest -k expression (it must select at least one test)")
    p.add_argument("--rig", metavar="FILE", default=None,
                   help="a rig of your own: its rig file (the profile's [dut] rig names it)")
    p.add_argument("--dispersion", default=None, metavar="FILE",
                   help="dispersion file (default: the rig's shipped dispersion.toml; "
                        "'none': nominal rig parameters, seeds only)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=option_type("campaign --workers"), default=None,
                       help=help_with_range("campaign --workers",
                                            "local Dask worker processes (default: the cores)"))
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                       help="run on an existing Dask cluster instead")
    p.add_argument("--connect-timeout-s", type=option_type("campaign --connect-timeout-s"),
                   default=10.0,
                   help=help_with_range("campaign --connect-timeout-s",
                                        "with --scheduler: give up when it does not answer "
                                        "within this (default: 10)"))
    p.add_argument("--out", default="campaign", help="output directory (default: campaign)")
    p.add_argument("--seed", type=option_type("--seed"), default=0,
                   help=help_with_range("--seed", "seed S of sample 0 (default: 0)"))
    p.add_argument("--timeout-s", type=option_type("campaign --timeout-s"), default=600.0,
                   help=help_with_range("campaign --timeout-s",
                                        "a sample running longer is killed and recorded as "
                                        "an error (default: 600)"))
    p.add_argument("--worst", type=option_type("campaign --worst"), default=1,
                   help=help_with_range("campaign --worst",
                                        "worst samples per measurement rerun with full "
                                        "recording (default: 1)"))
    p.add_argument("--max-reruns", type=option_type("campaign --max-reruns"), default=None,
                   help=help_with_range("campaign --max-reruns",
                                        "most samples rerun with full recording, failing ones "
                                        "first (default: proportionate to the campaign, one "
                                        "per ten samples, at least 1 and at most "
                                        f"{DEFAULT_MAX_RERUNS}; 0: none)"))
    p.add_argument("--isolation", choices=["fork", "process", "inprocess"], default=None,
                   help="fork (default on local workers): a fresh process per sample, "
                        "forked from one that imported the suites' dependencies once, "
                        "killed at --timeout-s; process (default with --scheduler): a new "
                        "interpreter per sample, the same isolation without the fork "
                        "server (which daemonic Dask workers may not start); inprocess: "
                        "pytest in the worker itself, but a hung sample cannot be killed "
                        "(reruns always use a new interpreter)")
    stop = p.add_mutually_exclusive_group()
    stop.add_argument("--sequential", action="store_true",
                      help="Wald's sequential probability ratio test between the profile's "
                           "[campaign] pass_probability and sequential_good_probability "
                           "(risks: 1 - confidence of passing the first, sequential_alpha of "
                           "failing the second), samples judged in index order; stops at a "
                           "boundary, inconclusive at --samples")
    stop.add_argument("--no-early-stop", action="store_true",
                      help="run all --samples even when the verdict is settled (default with "
                           "a [campaign] requirement: stop as soon as the remaining samples "
                           "cannot change the verdict)")
    p.add_argument("--no-progress", action="store_true", help="no progress display")
    p.set_defaults(func=_campaign)


def default_max_reruns(samples: int) -> int:
    """Reruns proportionate to the campaign: one per ten samples, 1 .. DEFAULT_MAX_RERUNS."""
    return max(1, min(DEFAULT_MAX_RERUNS, samples // 10))


def check_scheduler(address: str | None) -> None:
    """Refuse a ``--scheduler`` that is no Dask address (``tcp://HOST:PORT``)."""
    if address is None:
        return
    scheme, sep, rest = address.partition("://")
    host, _, port = rest.rpartition(":")
    if not sep or scheme not in ("tcp", "tls", "ws", "wss", "inproc") or not host \
            or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ConfigError(f"{address!r} is not a Dask scheduler address: give "
                          f"tcp://HOST:PORT with a port 1..65535", key="--scheduler")


def check_campaign_options(args: argparse.Namespace) -> tuple[Any, Any]:
    """Every option, alone and with the others, before anything starts (no worker, no file
    in ``--out``). Returns the profile and the dispersion (None: nominal)."""
    from hil.campaign.dispersion import load_dispersion
    from hil.cli.qualify import check_suites
    from hil.dut.profile import load_profile
    from hil.ownrig.cli_support import check_profile_rig, register_option_rig

    own_rig = register_option_rig(getattr(args, "rig", None))   # before the profile names it
    profile = load_profile(args.profile)
    check_profile_rig(own_rig, profile)
    check_suites(args.suite)
    check_keyword(args.keyword)
    check_bus_spec(args.bus)
    check_bus_for_dut(args.bus, profile.dut.kind, inprocess_twin=bool(profile.launch.inprocess))
    if args.bus == "inline" and args.clock != "lockstep":
        raise ConfigError("the inline bus calls the controller inside the lockstep loop: use "
                          "--clock lockstep, or a bus (softbus) for real time", key="--bus")
    check_scheduler(args.scheduler)
    dispersion = None
    if (args.dispersion or "").lower() != "none":
        path = args.dispersion or default_dispersion(profile.dut.rig)
        dispersion = load_dispersion(path, rig=profile.dut.rig)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{out} exists and is not a directory", key="--out")
    stopping_rule(args, profile)
    return profile, dispersion


def stopping_rule(args: argparse.Namespace, profile: Any) -> str:
    """The campaign's stopping rule (:mod:`hil.campaign.decision`): ``sequential`` with
    ``--sequential`` (the profile must state the SPRT), ``fixed`` without a requirement or with
    ``--no-early-stop``, else ``curtailed``."""
    req = profile.campaign
    if getattr(args, "sequential", False):
        if req is None:
            raise ConfigError("--sequential needs a [campaign] table stating pass_probability, "
                              "confidence, sequential_good_probability and sequential_alpha",
                              path=str(profile.path), key="campaign")
        for key in ("sequential_good_probability", "sequential_alpha"):
            if getattr(req, key) is None:
                raise ConfigError(f"--sequential needs [campaign] {key} (see "
                                  f"docs/guide/campaigns.md, 'Early decisions')",
                                  path=str(profile.path), key=f"campaign.{key}")
        return "sequential"
    if req is None or getattr(args, "no_early_stop", False):
        return "fixed"
    return "curtailed"


def _campaign(args: argparse.Namespace) -> int:
    from hil.campaign.engine import Campaign, CampaignPlan, dask_client, map_samples
    from hil.campaign.progress import Progress
    from hil.campaign.selection import check_selection
    from hil.dut.build import ensure_built

    profile, dispersion = check_campaign_options(args)
    if args.isolation is None:
        args.isolation = "process" if args.scheduler else "fork"
    max_reruns = (default_max_reruns(args.samples) if args.max_reruns is None
                  else args.max_reruns)
    plan = CampaignPlan(profile=profile, samples=args.samples, seed=args.seed, bus=args.bus,
                        clock=args.clock, suites=args.suite, dispersion=dispersion,
                        timeout_s=args.timeout_s, keyword=args.keyword, worst=args.worst,
                        max_reruns=max_reruns, isolation=args.isolation,
                        rule=stopping_rule(args, profile))
    check_selection(plan.task(0))            # -k and --suite select at least one test
    build_dir = None
    if args.scheduler is None and args.bus != "inline" and profile.build is not None:
        print(f"hil: building {profile.name} (cached after the first time) ...",
              file=sys.stderr)
        build = ensure_built(profile)
        build_dir = Path(str(build["build_dir"])) if build.get("build_dir") else None
    if args.scheduler is None:
        check_launchable(profile, bus=args.bus, clock=args.clock, build=build_dir)
    phase("campaign:built")
    out = prepare_out_dir(args.out)
    staging = Staging(out, prefix=STAGING_PREFIX, outputs=OUTPUTS, record=RECORD_NAME)
    engine = ({"kind": "scheduler", "address": args.scheduler} if args.scheduler else
              {"kind": "local", "workers": args.workers or os.cpu_count() or 1})
    engine["isolation"] = args.isolation
    campaign = Campaign(plan, staging.path, engine=engine)
    label = f"campaign of {profile.name}"
    where = (f"Dask scheduler {args.scheduler}" if args.scheduler
             else f"{engine['workers']} local workers")
    print(f"hil: {label}: {args.samples} samples from seed {args.seed} ({args.bus}, "
          f"{args.clock}, suites {args.suite}; dispersion "
          f"{dispersion.path if dispersion else 'none'}; "
          f"{where}; {_rule_text(plan)})",
          file=sys.stderr)
    _say_reach(plan)
    # nothing in --out changes until the cluster is there: a campaign that cannot start
    # leaves the previous one as it was
    with dask_client(workers=args.workers, scheduler=args.scheduler,
                     connect_timeout_s=args.connect_timeout_s) as client:
        phase("campaign:cluster")
        engine["workers"] = len(client.scheduler_info().get("workers", {}))
        try:
            # campaign.json says "running" until it is not (the previous one kept as
            # campaign.previous.json); a signal during begin() arrives right after it, here
            staging.begin(campaign.document())
            phase("campaign:started")
            with staging.writing():
                progress = Progress(args.samples, label, enabled=not args.no_progress)

                def on_sample(sample: dict[str, Any]) -> bool:
                    decided = campaign.add(sample)
                    progress.update(sample)
                    phase("campaign:sample")
                    return decided
                try:
                    map_samples(client, [plan.task(i) for i in range(args.samples)],
                                on_sample, prefix=f"agrihil-{plan.campaign_id}-sample")
                finally:
                    progress.close()
                if campaign.decision is not None:
                    _say_decided(campaign)
                    if args.max_reruns is None:   # reruns in proportion to what ran
                        plan.max_reruns = default_max_reruns(len(campaign.samples))
                campaign.write()
                phase("campaign:written")
                _rerun(campaign, client, staging.path)
            campaign.status = "complete"
        except KeyboardInterrupt:
            campaign.status = "interrupted"
            raise
        finally:
            if campaign.status == "running":
                campaign.status = "interrupted"
            if staging.path.exists():
                with signals_held(), staging.writing():   # a full disk names --out
                    campaign.close()
                    campaign.write()
                    _write_report(staging.path)
                    phase("campaign:promote")
                    staging.promote()
    return _report(campaign.document(), out)


def _rule_text(plan: Any) -> str:
    return {"fixed": "every sample run",
            "curtailed": "stops when the verdict is settled",
            "sequential": "Wald's SPRT"}[plan.rule]


def _say_reach(plan: Any) -> None:
    """Say up front when --samples is too few to demonstrate the requirement at all."""
    from hil.campaign.stats import samples_needed

    req = plan.profile.campaign
    if req is None or plan.rule == "sequential":
        return
    need = samples_needed(req.pass_probability, req.confidence)
    if plan.samples < need:
        print(f"hil: {plan.samples} samples cannot demonstrate {req.pass_probability:g} at "
              f"{req.confidence:.0%} confidence (at least {need} with none failing): this "
              f"campaign can end fail or inconclusive, not pass", file=sys.stderr)


def _say_decided(campaign: Any) -> None:
    """The one console line of an early decision: verdict, samples used and saved, why."""
    d = campaign.decision
    total = campaign.plan.samples
    run = len(campaign.samples)
    print(f"hil: decided after {run} of {total} samples ({total - run} saved, "
          f"{(total - run) / total:.0%}): {d.verdict.upper()}: {d.reason}", file=sys.stderr)


def default_dispersion(rig: str) -> Path:
    """The rig's shipped dispersion file (from the rig's own bus contract: the core names no
    rig)."""
    from hil.contract.registry import dispersion_file

    return dispersion_file(rig)


def _rerun(campaign: Any, client: Any, out: Path) -> None:
    from hil.campaign.engine import map_samples, rerun_selection, same_measurements

    plan = campaign.plan
    doc = campaign.document()
    chosen = rerun_selection(doc, worst=plan.worst, max_reruns=plan.max_reruns)
    if not chosen:
        return
    why = _why(doc)
    print(f"hil: rerunning {len(chosen)} of {plan.samples} samples with full recording "
          f"(failing first, then the worst per measurement; at most {plan.max_reruns}: "
          f"--max-reruns): {', '.join(map(str, chosen))}", file=sys.stderr)
    phase("campaign:rerun")
    by_index = {s["index"]: s for s in campaign.samples}
    tasks = {i: plan.task(i, record="full", out_dir=str((out / "samples" / f"{i:04d}").resolve()))
             for i in chosen}

    def on_rerun(sample: dict[str, Any]) -> None:
        task = tasks[sample["index"]]
        original = by_index.get(sample["index"], {})
        campaign.reruns.append({
            "index": sample["index"], "seed": task.seed, "why": why.get(sample["index"], []),
            "dir": f"samples/{sample['index']:04d}",
            "report": f"samples/{sample['index']:04d}/report.html",
            "command": task.qualify_command(), "verdict": sample["verdict"],
            "error": sample.get("error"),
            # the rerun's bus conformance needs its bus log, which the measurements-only
            # sample did not keep: every other measurement must be the sample's, bit for bit;
            # a rerun that could not run (its disk full, its DUT gone) says nothing either way
            "reproduced": None if sample["verdict"] == "error" else same_measurements(
                [m for m in sample["measurements"] if not is_conformance(m["name"])],
                original.get("measurements", [])),
            # judged only here: a failed one fails the campaign (Campaign.document)
            "conformance_failed": sorted({m["name"] for m in sample["measurements"]
                                          if is_conformance(m["name"])
                                          and m.get("outcome") == "fail"})})
    map_samples(client, list(tasks.values()), on_rerun,
                prefix=f"agrihil-{plan.campaign_id}-rerun")


def _why(doc: dict[str, Any]) -> dict[int, list[str]]:
    why: dict[int, list[str]] = {}
    for i in doc["summary"]["failing_samples"]:
        why.setdefault(i, []).append("failed")
    for key, stats in doc["measurements"].items():
        for i in stats["worst"][:1]:
            why.setdefault(i, []).append(f"worst {key}")
    return why


def _write_report(out: Path) -> None:
    from hil.report.campaign_page import write_campaign_html

    try:
        write_campaign_html(out)
    except Exception as exc:  # the record is written; say loudly the page is not
        if is_storage_error(exc):
            raise                # a disk that refuses a write is exit 2 naming --out
        print(f"hil: report.html not written: {exc}", file=sys.stderr)


def _report(doc: dict[str, Any], out: Path) -> int:
    s = doc["summary"]
    for rerun in doc["reruns"]:
        flag = ("" if rerun["reproduced"] else "  (NOT reproduced: see its report)"
                if rerun["reproduced"] is not None
                else f"  (the rerun failed: {rerun.get('error') or 'no reason given'})")
        print(f"hil: sample {rerun['index']} ({'; '.join(rerun['why']) or 'rerun'}): "
              f"{rerun['command']}{flag}", file=sys.stderr)
    rate = s["pass_rate"]
    print(f"hil: campaign {doc['dut']['name']}: {s['verdict'].upper()}: {s['reason']}; "
          f"{s['passed']}/{s['judged']} passed"
          + (f" ({rate:.1%}; exact two-sided 95 % interval of the pass rate "
             f"{s['ci95'][0]:.3f}-{s['ci95'][1]:.3f})" if rate is not None else "")
          + f"; {s['errors']} errors; {_used(doc)}{doc['wall_s']:.0f} s; "
            f"report: {out / 'report.html'}",
          file=sys.stderr)
    return EXIT_BY_VERDICT.get(s["verdict"], 2)


def _used(doc: dict[str, Any]) -> str:
    d = doc.get("decision") or {}
    if not d.get("early"):
        return ""
    return f"{d['samples_run']} samples used, {d['samples_saved']} saved; "
