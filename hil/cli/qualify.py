"""``hil qualify``: run the standard suites against one DUT and write its qualification.

    hil qualify dut_profiles/fertilizer-piecewise-pid-daemon.toml --out out
    hil qualify PROFILE --bus socketcan:vcan0 --clock realtime --suite full,robustness

Writes ``record.json``, ``junit.xml``, ``report.html`` and one directory per scenario run
(bus logs, traces, the DUT's output) into ``--out``. Exit 0 when the DUT qualifies, 1 when it
does not, 2 on setup errors (bad profile, build failure, invalid bench timing).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

from hil.cli.args import add_bus_clock
from hil.dut.build import ensure_built
from hil.dut.profile import load_profile
from hil.errors import HilError

DEFAULT_SUITES = "fast,robustness"
EXIT_BY_VERDICT = {"pass": 0, "fail": 1}


def suites_dir() -> Path:
    import test_suites

    return Path(test_suites.__file__).resolve().parent


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    qualify = subparsers.add_parser("qualify", help="qualify a DUT and write its report")
    qualify.add_argument("profile", help="DUT profile (TOML)")
    add_bus_clock(qualify)
    qualify.add_argument("--suite", default=DEFAULT_SUITES,
                         help=f"comma-separated suites: fast, full (the papers' 3 repeats), "
                              f"robustness, busload (real time on a bus loaded near its "
                              f"bit rate, ~1 min), all (default: {DEFAULT_SUITES})")
    qualify.add_argument("--out", default="out", help="output directory (default: out)")
    qualify.add_argument("--seed", type=int, default=None,
                         help="added to every scenario's seed (default: 0)")
    qualify.add_argument("-k", dest="keyword", default=None,
                         help="only tests matching this pytest -k expression")
    qualify.add_argument("--quiet", action="store_true", help="one line per test file")
    # --- campaign (issue 15): reproduce one campaign sample with its dispersed rig -----------
    qualify.add_argument("--rig-override", metavar="KEY=VALUE", action="append", default=[],
                         help="override a rig config parameter (dotted key, TOML value) on top "
                              "of the profile's [rig]; repeatable. `hil campaign` prints these "
                              "for each sample it reruns")
    qualify.set_defaults(func=_qualify)


def pytest_args(args: argparse.Namespace, out: Path) -> list[str]:
    root = suites_dir()
    argv = [str(root), "-c", str(root / "pytest.ini"), "--rootdir", str(root),
            "-p", "no:cacheprovider",
            "--hil-dut", str(args.profile), "--hil-bus", args.bus, "--hil-clock", args.clock,
            "--hil-report", str(out), "--hil-suite", args.suite,
            "--junitxml", str(out / "junit.xml"), "-o", "junit_family=xunit2",
            "-q" if args.quiet else "-v"]
    if args.seed is not None:
        argv += ["--hil-seed", str(args.seed)]
    if args.keyword:
        argv += ["-k", args.keyword]
    for item in getattr(args, "rig_override", []):   # campaign (issue 15)
        argv += ["--hil-rig-override", item]
    return argv


def _qualify(args: argparse.Namespace) -> int:
    import pytest

    profile = load_profile(args.profile)          # a bad profile never starts a run
    if args.rig_override:                          # campaign (issue 15): checked up front
        from hil.campaign.overrides import parse_overrides

        parse_overrides(args.rig_override, rig=profile.dut.rig, base=profile.rig_config)
    out = Path(args.out)
    if out.exists() and (out / "record.json").exists():
        shutil.rmtree(out / "runs", ignore_errors=True)
        (out / "record.json").unlink()
    out.mkdir(parents=True, exist_ok=True)
    if args.bus != "inline" and profile.build is not None:
        print(f"hil: building {profile.name} (cached after the first time) ...",
              file=sys.stderr)
        build = ensure_built(profile)
        print(f"hil: build {'cached' if build.get('cached') else 'done'}: "
              f"{build.get('build_dir')}", file=sys.stderr)
    print(f"hil: qualifying {profile.name} {profile.dut.version} on the {profile.dut.rig} rig "
          f"({args.bus}, {args.clock}, suites {args.suite})", file=sys.stderr)
    code = pytest.main(pytest_args(args, out))
    record_path = out / "record.json"
    if not record_path.exists():
        raise HilError(f"the suites wrote no record (pytest exit {int(code)}); see the "
                       f"output above")
    record = json.loads(record_path.read_text())
    verdict = record["verdict"]
    counts: dict[str, int] = {}
    for m in record["measurements"]:
        counts[m["outcome"]] = counts.get(m["outcome"], 0) + 1
    summary = ", ".join(f"{n} {k}" for k, n in sorted(counts.items())) or "no measurements"
    print(f"hil: {profile.name}: {verdict.upper()} ({summary}) in {record['wall_s']:.1f} s; "
          f"report: {out / 'report.html'}", file=sys.stderr)
    return EXIT_BY_VERDICT.get(verdict, 2)
