"""``hil qualify``: run the standard suites against one DUT and write its qualification.

    hil qualify dut_profiles/fertilizer-piecewise-pid-daemon.toml --out out
    hil qualify PROFILE --bus socketcan:vcan0 --clock realtime --suite full,robustness

Writes ``record.json``, ``junit.xml``, ``report.html`` and one directory per scenario run
(bus logs, traces, the DUT's output) into ``--out``. Exit 0 when the DUT qualifies, 1 when it
does not, 2 on setup errors (bad option or profile, build failure, invalid bench timing), 130
when interrupted.

What an interruption leaves (see docs/guide/reliability.md): before anything runs,
``record.json`` is replaced (atomically) by a record with the verdict ``interrupted`` (the one
it replaces is kept as ``record.previous.json``); the new qualification writes into a hidden
staging directory inside ``--out`` and only when it ends (finished or interrupted) are its
runs, report and record moved in, the record last. A kill at any moment leaves a record
that no gate passes.
"""

from __future__ import annotations

import argparse
import datetime as dt
import errno
import json
import re
import sys
import time
from pathlib import Path
from typing import Any

from hil.cli.args import (
    add_bus_clock,
    check_bus_for_dut,
    check_bus_spec,
    check_keyword,
    check_launchable,
    check_seed,
    prepare_out_dir,
)
from hil.cli.phases import phase
from hil.dut.build import ensure_built, with_build_id
from hil.dut.profile import DutProfile, load_profile
from hil.errors import ConfigError, HilError
from hil.ownrig.cli_support import check_profile_rig, register_option_rig, suite_location_of
from hil.record.atomic import write_json_atomic
from hil.record.staging import Staging, signals_held

DEFAULT_SUITES = "fast,robustness"
#: an ISOBUS implement ([wiring] isobus = true) takes its rate from the rig's Task Controller:
#: its qualification is the isobus suite (the others give the set-point by FertSetpoint)
DEFAULT_ISOBUS_SUITES = "isobus"
EXIT_BY_VERDICT = {"pass": 0, "fail": 1, "interrupted": 130}
#: what a qualification writes into --out (moved in from the staging directory, record last)
OUTPUTS = ("runs", "junit.xml", "report.html",
           "as-applied-*.geojson")   # a field run's as-applied map, beside the report
STAGING_PREFIX = ".qualify-"
SCHEMA = "agrihil.qualification/1"


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    qualify = subparsers.add_parser("qualify", help="qualify a DUT and write its report")
    qualify.add_argument("profile", help="DUT profile (TOML)")
    add_bus_clock(qualify)
    qualify.add_argument("--suite", default=None,
                         help=f"comma-separated suites: fast, full (the papers' other runs: "
                              f"[F]'s 2nd and 3rd accuracy repeats on the fertilizer rig, "
                              f"[D]'s 1-3 and 5-7 km/h field runs on the depth rig), "
                              f"robustness, busload (real time on a bus loaded near its "
                              f"bit rate, ~1 min), isobus (field runs under the rig's Task "
                              f"Controller), all (default: {DEFAULT_SUITES}; "
                              f"{DEFAULT_ISOBUS_SUITES} for an ISOBUS implement)")
    qualify.add_argument("--out", default="out", help="output directory (default: out)")
    qualify.add_argument("--seed", type=int, default=None,
                         help="added to every scenario's seed (default: 0)")
    qualify.add_argument("-k", dest="keyword", default=None,
                         help="only tests matching this pytest -k expression")
    qualify.add_argument("--quiet", action="store_true", help="one line per test file")
    qualify.add_argument("--build-id", default=None,
                         help="the DUT's build id for the record (a CI job passes its commit); "
                              "default: the profile's [dut] build_id")
    qualify.add_argument("--rig", metavar="FILE", default=None,
                         help="a rig of your own: its rig file (the profile's [dut] rig names "
                              "it by the file's name)")
    # --- campaign (issue 15): reproduce one campaign sample with its dispersed rig -----------
    qualify.add_argument("--rig-override", metavar="KEY=VALUE", action="append", default=[],
                         help="override a rig config parameter (dotted key, TOML value) on top "
                              "of the profile's [rig]; repeatable. `hil campaign` prints these "
                              "for each sample it reruns")
    qualify.set_defaults(func=_qualify)


def default_suites(profile: DutProfile) -> str:
    """The suites a profile is qualified on when ``--suite`` is not given."""
    return DEFAULT_ISOBUS_SUITES if profile.wiring.isobus else DEFAULT_SUITES


def check_suites(text: str) -> list[str]:
    """The suite names of ``--suite``; a name that is no suite is refused, naming them all."""
    from hil.pytest_plugin import SUITES

    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in (*SUITES, "all")]
    if unknown or not names:
        raise ConfigError(f"{', '.join(unknown) or repr(text)}: no such suite; choose from "
                          f"{', '.join(SUITES)}, all (comma-separated)", key="--suite")
    return names


def pytest_args(args: argparse.Namespace, out: Path, rig: str) -> list[str]:
    """pytest's argv for the suites of ``rig`` only (the other rigs' suites are not even
    collected), writing into ``out``."""
    suites, ini = suite_location_of(rig)
    argv = [str(suites), "-c", str(ini), "--rootdir", str(ini.parent),
            "-p", "no:cacheprovider", "-p", "no:benchmark",
            "--hil-dut", str(args.profile), "--hil-bus", args.bus, "--hil-clock", args.clock,
            "--hil-report", str(out), "--hil-suite", args.suite,
            "--junitxml", str(out / "junit.xml"), "-o", "junit_family=xunit2",
            "-q" if args.quiet else "-v"]
    if args.seed is not None:
        argv += ["--hil-seed", str(args.seed)]
    if args.keyword:
        argv += ["-k", args.keyword]
    if getattr(args, "build_id", None) is not None:
        argv += ["--hil-build-id", args.build_id]
    for item in getattr(args, "rig_override", []):   # campaign (issue 15)
        argv += ["--hil-rig-override", item]
    return argv


def interrupted_record(profile: DutProfile, args: argparse.Namespace, *, run_id: str,
                       note: str) -> dict[str, Any]:
    """A qualification record that says "this qualification did not finish": valid for the
    gate and the report, with no measurement and the verdict ``interrupted``."""
    return {"schema": SCHEMA, "run_id": run_id,
            "started_at": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            "wall_s": 0.0, "verdict": "interrupted", "complete": False,
            "tests_planned": None, "tests_completed": 0, "tests_not_run": [],
            "note": note,
            "dut": {**profile.identity(), "parameters": profile.parameters},
            "rig": {"name": profile.dut.rig}, "bus": args.bus, "clock": args.clock,
            "seed": args.seed, "suites": check_suites(args.suite or default_suites(profile)),
            "versions": {},
            "limits": {}, "measurements": [], "tests": [], "runs": [], "timing": None}


def _qualify(args: argparse.Namespace) -> int:
    started = time.monotonic()
    staging: Staging | None = None
    try:
        profile, staging = _prepare(args)
        # from here on, whatever happens, record.json says this qualification did not
        # finish until it has; the previous record is kept (record.previous.json). A signal
        # during begin() is held and arrives right after it, inside the try below
        staging.begin(interrupted_record(profile, args, run_id=staging.run_id,
                                         note="the qualification started and has not "
                                              "finished (or was killed)"))
    except KeyboardInterrupt:
        if staging is None or not staging.path.exists():
            print("hil: interrupted before the qualification began; --out is untouched",
                  file=sys.stderr)
            return 130
        _finish(staging, profile, args, None)
        raise
    out = staging.out
    code: int | None = None
    try:
        phase("qualify:staged")
        with staging.writing():   # a full disk names --out and leaves no staging behind
            code = _run_suites(args, profile, staging.path)
    finally:
        if staging.path.exists():
            _finish(staging, profile, args, code)
    record = json.loads((out / "record.json").read_text())
    verdict = record["verdict"]
    if code is not None and not record.get("tests") and verdict == "error":
        raise HilError(f"the suites ran no test (pytest exit {code}); see the output above")
    _print_summary(record, profile, out, wall_s=time.monotonic() - started)
    return EXIT_BY_VERDICT.get(verdict, 2)


def _finish(staging: Staging, profile: DutProfile, args: argparse.Namespace,
            code: int | None) -> None:
    """Promote what the suites staged.

    When they wrote no record: an interruption (``code`` None: they raised) is recorded as
    ``interrupted``; pytest returning without one (a usage or internal error) is an
    ``error``, never an interruption.
    """
    record = staging.path / "record.json"
    with signals_held(), staging.writing():   # a failed write names --out, cleans the staging
        if not record.exists():
            if code is None:
                doc = interrupted_record(profile, args, run_id=staging.run_id,
                                         note="interrupted before the suites wrote their "
                                              "record")
            else:
                doc = {**interrupted_record(profile, args, run_id=staging.run_id,
                                            note=f"the suites did not run (pytest exit "
                                                 f"{code}); see the output above"),
                       "verdict": "error"}
            write_json_atomic(record, doc)
        phase("qualify:promote")          # held: arrives once the outputs are in
        staging.promote()


def _prepare(args: argparse.Namespace) -> tuple[DutProfile, Staging]:
    """Check every option and build the DUT: nothing in ``--out`` changes before this ends."""
    # every option is checked before anything runs: a bad one is exit 2, never the DUT's fault
    # a bad profile (or build id) never starts a run
    own_rig = register_option_rig(getattr(args, "rig", None))   # before the profile names it
    profile = with_build_id(load_profile(args.profile), args.build_id)
    check_profile_rig(own_rig, profile)
    from hil.cli.profile import refuse_problems

    refuse_problems(profile)                       # what `hil profile check` would report
    if args.suite is None:
        args.suite = default_suites(profile)
    if args.rig_override:                          # campaign (issue 15): checked up front
        from hil.campaign.overrides import parse_overrides

        parse_overrides(args.rig_override, rig=profile.dut.rig, base=profile.rig_config)
    check_suites(args.suite)
    check_seed(args.seed)
    check_keyword(args.keyword)
    check_bus_spec(args.bus)
    check_bus_for_dut(args.bus, profile.dut.kind,
                      inprocess_twin=bool(profile.launch.inprocess))
    out = prepare_out_dir(args.out)
    rig = profile.dut.rig
    suite_location_of(rig)                         # a rig without suites is a setup error
    _build(args, profile)                          # a DUT that cannot start never runs
    return profile, Staging(out, prefix=STAGING_PREFIX, outputs=OUTPUTS,
                            record="record.json")


def _build(args: argparse.Namespace, profile: DutProfile) -> None:
    """Build the DUT (cached) and check that its command can be executed: both before
    ``--out`` is touched, so a DUT that cannot start is a setup error, not three failed
    tests."""
    build_dir: Path | None = None
    if args.bus != "inline" and profile.build is not None:
        print(f"hil: building {profile.name} (cached after the first time) ...",
              file=sys.stderr)
        build = ensure_built(profile)
        print(f"hil: build {'cached' if build.get('cached') else 'done'}: "
              f"{build.get('build_dir')}", file=sys.stderr)
        build_dir = Path(str(build["build_dir"])) if build.get("build_dir") else None
    check_launchable(profile, bus=args.bus, clock=args.clock, build=build_dir)
    phase("qualify:built")


def _run_suites(args: argparse.Namespace, profile: DutProfile, stage: Path) -> int:
    import pytest

    from hil.cli.phase_marks import OneDuration, PhaseMarks

    print(f"hil: qualifying {profile.name} {profile.dut.version} on the {profile.dut.rig} rig "
          f"({args.bus}, {args.clock}, suites {args.suite})", file=sys.stderr)
    phase("qualify:suites")
    code = int(pytest.main(pytest_args(args, stage, profile.dut.rig),
                           plugins=[PhaseMarks(), OneDuration()]))
    _refuse_unwritten_runs(stage)
    return code


def _refuse_unwritten_runs(stage: Path) -> None:
    """A run whose traces or bus logs the disk refused (its recorder noted it in its record's
    ``recorder_problems``) makes the qualification a storage error, as a refused write of
    the record does: exit 2 naming ``--out``, the staging removed, the previous record kept.

    Raises
    ------
    OSError
        With the refused write's errno (``[Errno N]`` in the note), else EIO.
    """
    for path in sorted((stage / "runs").rglob("record.json")) if (stage / "runs").is_dir() \
            else ():
        try:
            problems = json.loads(path.read_text(encoding="utf-8")).get("recorder_problems")
        except (OSError, ValueError):
            continue
        if problems:
            text = "; ".join(map(str, problems))
            found = re.search(r"\[Errno (\d+)\]", text)
            code = int(found.group(1)) if found else errno.EIO
            raise OSError(code, f"the files of run {path.parent.name} could not all be "
                                f"written ({text})")


def _print_summary(record: dict[str, Any], profile: DutProfile, out: Path, *,
                   wall_s: float) -> None:
    verdict = record["verdict"]
    counts: dict[str, int] = {}
    for m in record["measurements"]:
        counts[m["outcome"]] = counts.get(m["outcome"], 0) + 1
    summary = ", ".join(f"{n} {k}" for k, n in sorted(counts.items())) or "no measurements"
    if verdict == "interrupted":
        done = record.get("tests_completed") or 0
        planned = record.get("tests_planned")
        print(f"hil: {profile.name}: INTERRUPTED after {done}"
              f"{f' of {planned}' if planned is not None else ''} tests ({summary}); "
              f"{out / 'record.json'} says so (no gate passes it)", file=sys.stderr)
        return
    print(f"hil: {profile.name}: {verdict.upper()} ({summary}) in {wall_s:.1f} s (wall time, "
          f"build and report included); report: {out / 'report.html'}", file=sys.stderr)
