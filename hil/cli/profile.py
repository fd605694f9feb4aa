"""``hil profile``: check DUT profiles and show what they resolve to.

    hil profile check dut_profiles/*.toml
    hil profile show dut_profiles/fertilizer-piecewise-pid-firmware.toml --bus softbus

Exit 0 when every profile is valid, 2 when one is not (the error names file and key).
"""

from __future__ import annotations

import argparse
import json
import sys

from hil.dut.factory import load_controller
from hil.dut.process import command_line
from hil.dut.profile import DutProfile, load_profile
from hil.errors import ConfigError


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    profile = subparsers.add_parser("profile", help="check or show DUT profiles")
    sub = profile.add_subparsers(dest="profile_command", metavar="ACTION")
    sub.required = True
    check = sub.add_parser("check", help="validate DUT profiles (exit 2 on the first error)")
    check.add_argument("files", nargs="+", help="profile TOML files")
    check.set_defaults(func=_check)
    show = sub.add_parser("show", help="print a profile as resolved (JSON)")
    show.add_argument("file")
    show.add_argument("--bus", default="softbus", help="bus spec to expand {bus} with")
    show.add_argument("--clock", choices=["lockstep", "realtime"], default="lockstep")
    show.set_defaults(func=_show)


def check_profile(path: str) -> DutProfile:
    """Everything that can be checked without starting the DUT."""
    profile = load_profile(path)
    if profile.launch.inprocess:
        load_controller(profile)    # imports it and hands it the parameters
    return profile


def _check(args: argparse.Namespace) -> int:
    failed = 0
    for path in args.files:
        try:
            profile = check_profile(path)
        except ConfigError as exc:
            print(f"hil: error: {exc}", file=sys.stderr)
            failed += 1
            continue
        print(f"ok  {path}: {profile.name} {profile.dut.version} ({profile.dut.kind}, "
              f"{profile.dut.rig}, {len(profile.parameters)} parameters, "
              f"{len(profile.limits)} limits)")
    return 2 if failed else 0


def _show(args: argparse.Namespace) -> int:
    profile = check_profile(args.file)
    out = {"identity": profile.identity(),
           "command": command_line(profile, bus=args.bus, clock=args.clock)
           if profile.launch.command else None,
           "inprocess": profile.launch.inprocess or None,
           "parameters": profile.parameters,
           "limits": {k: {"low": v.low, "high": v.high} for k, v in profile.limits.items()}}
    print(json.dumps(out, indent=2))
    return 0
