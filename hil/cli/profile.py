"""``hil profile``: check DUT profiles, show what they resolve to, and bind a database.

    hil profile check dut_profiles/*.toml
    hil profile show dut_profiles/fertilizer-piecewise-pid-firmware.toml --bus softbus
    hil profile bind my_controller.dbc --rig fertilizer -o my_controller.binding.toml

``check`` validates the profile, then everything a run would find later: the binding of the
rig's quantities to the database (``hil.contract.checks``: every problem at once), the
database's ids against the wiring, ``wiring.command_ids``, ``build.sources``, and prints the
limits the DUT will be judged against, each with where it comes from (the catalogue's default
and its standard, tightened, loosened with the profile's reason, information only). Exit 0
when every profile is valid, 2 when one is not (each error names file, key and fix).
``bind`` writes a starting binding, ``# TODO:`` where it could not decide.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hil.contract.binding import load_binding
from hil.contract.checks import Problem, check_binding, check_profile_wiring
from hil.contract.database import BusDatabase
from hil.contract.registry import rig_contract
from hil.dut.base import DutError
from hil.dut.build import build_dir, ensure_built, expand, missing_sources
from hil.dut.code_identity import program_of
from hil.dut.factory import load_controller
from hil.dut.process import command_line
from hil.dut.profile import DutProfile, database_path, load_profile
from hil.effective_limits import EffectiveLimit, counts, effective_limits
from hil.errors import ConfigError, FrameError


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    profile = subparsers.add_parser("profile", help="check, show or bind DUT profiles")
    sub = profile.add_subparsers(dest="profile_command", metavar="ACTION")
    sub.required = True
    check = sub.add_parser("check", help="validate DUT profiles and their bindings (exit 2 "
                                         "when one is invalid; every problem is listed)")
    check.add_argument("files", nargs="+", help="profile TOML files")
    check.add_argument("--build", action="store_true",
                       help="build a firmware DUT first (cached), so that its binary is "
                            "checked too")
    check.add_argument("-q", "--quiet", action="store_true",
                       help="one line per profile, without its effective limits")
    check.set_defaults(func=_check)
    show = sub.add_parser("show", help="print a profile as resolved (JSON), its effective "
                                       "limits and the code under test included")
    show.add_argument("file")
    show.add_argument("--bus", default="softbus", help="bus spec to expand {bus} with")
    show.add_argument("--clock", choices=["lockstep", "realtime"], default="lockstep")
    show.set_defaults(func=_show)
    bind = sub.add_parser("bind", help="write a starting binding of a rig's quantities to a "
                                       "CAN database (DBC, KCD, ARXML, SYM)")
    bind.add_argument("database", help="the controller's CAN database")
    bind.add_argument("--rig", default="fertilizer", help="the rig (default: fertilizer)")
    bind.add_argument("-o", "--output", help="write the binding here (default: stdout)")
    bind.set_defaults(func=_bind)


def check_profile(path: str) -> DutProfile:
    """Everything of the profile itself that can be checked without starting the DUT."""
    profile = load_profile(path)
    if profile.launch.inprocess:
        load_controller(profile)    # imports it and hands it the parameters
    return profile


def profile_problems(profile: DutProfile) -> list[Problem]:
    """What a run of ``profile`` would trip on: its binding, wiring and build sources.

    Returns
    -------
    list of Problem
        Errors and notes (``note=True``), every one found.
    """
    src = str(profile.path or "")
    out: list[Problem] = [
        Problem(src, "build.sources", f"{name!r} does not exist ({where})",
                "a path relative to the project root, or {profile_dir}/...")
        for name, where in missing_sources(profile)]
    out += program_problems(profile)
    try:
        contract = rig_contract(profile.dut.rig, profile.rig_config, src)
        binding = load_binding(contract.binding_file)
    except ConfigError as exc:
        return [*out, Problem(exc.path or src, exc.key or "wiring.binding",
                              str(exc).split("] ", 1)[-1] if exc.key else str(exc))]
    try:
        db = BusDatabase(binding.database)
    except FrameError as exc:
        return [*out, Problem(binding.source, "database", str(exc),
                              "a database cantools reads (DBC, KCD, ARXML, SYM)")]
    out += check_binding(contract, binding, db=db)
    database = database_path(profile.wiring.database, profile.path) \
        if profile.wiring.database else None
    out += check_profile_wiring(profile, contract, binding, database=database,
                                bound=bool(profile.wiring.binding))
    return out


def program_problems(profile: DutProfile, *, build: Path | None = None) -> list[Problem]:
    """The program the DUT's command runs must exist: a daemon's script, module or
    executable; a firmware's binary, which ``[build] artifacts`` must list and, once built
    (``build``, else the cache entry if complete), the build must have made.

    Returns
    -------
    list of Problem
        Errors naming ``launch.command`` (or ``build.artifacts``), and a note for a firmware
        not built yet.
    """
    if not profile.launch.command or profile.dut.kind in ("physical", "inprocess"):
        return []
    src = str(profile.path or "")
    first = profile.launch.command[0]
    if profile.dut.kind == "firmware" and "{build_dir}" in first and profile.build is not None:
        if first not in profile.build.artifacts:
            return [Problem(src, "build.artifacts", f"the launch command runs {first}, which "
                            f"the build does not list among what it makes "
                            f"({', '.join(profile.build.artifacts) or 'none'})",
                            f'artifacts = ["{first}"]')]
        if build is None and not missing_sources(profile):
            entry = build_dir(profile)
            build = entry if (entry / ".built").exists() else None
        if build is None:
            return [Problem(src, "launch.command", f"{first} is not built yet: checked after "
                            "its build (hil profile check --build builds it)", note=True)]
    argv = [expand(a, profile, build=build) for a in profile.launch.command if a != "{params}"]
    program = program_of(argv)
    if not program.problem:
        return []
    what = {"executable": "the program it runs", "script": "the script it runs"}.get(
        program.what, program.what)
    fix = ("rebuild it (the cache entry lacks it)" if profile.dut.kind == "firmware"
           else "a path relative to the project root, or {profile_dir}/..., that exists")
    return [Problem(src, "launch.command", f"{what}: {program.problem}", fix)]


def refuse_problems(profile: DutProfile) -> None:
    """Refuse, before a run, a profile that ``hil profile check`` would report errors for.

    ``hil run`` and ``hil qualify`` call it up front, so a binding, wiring or build problem
    (a ``command_ids`` typo included) is the same setup error in every command, never a run
    that starts and then fails.

    Raises
    ------
    ConfigError
        Naming the first problem's file and key, with how many more there are.
    """
    errors = [p for p in profile_problems(profile) if not p.note]
    if not errors:
        return
    first = errors[0]
    more = (f"; and {len(errors) - 1} more problem(s): `hil profile check {profile.path}` "
            "lists them all") if len(errors) > 1 else ""
    fix = f" (fix: {first.fix})" if first.fix else ""
    raise ConfigError(f"{first.message}{fix}{more}", path=first.path or None,
                      key=first.key or None)


def _check(args: argparse.Namespace) -> int:
    failed = 0
    for path in args.files:
        try:
            profile = check_profile(path)
            if args.build and profile.build is not None:
                print(f"hil: building {profile.name} (cached after the first time) ...",
                      file=sys.stderr)
                ensure_built(profile)
        except (ConfigError, DutError) as exc:
            print(f"hil: error: {exc}", file=sys.stderr)
            failed += 1
            continue
        problems = profile_problems(profile)
        errors = [p for p in problems if not p.note]
        for problem in problems:
            kind = "note" if problem.note else "error"
            print(f"hil: {kind}: {problem}", file=sys.stderr)
        if errors:
            failed += 1
            continue
        limits = profile_limits(profile)
        judged, info = counts(limits)
        print(f"ok  {path}: {profile.name} {profile.dut.version} ({profile.dut.kind}, "
              f"{profile.dut.rig}, {len(profile.parameters)} parameters, "
              f"{len(profile.limits)} limits in the profile; {judged} measurements judged, "
              f"{info} information only)")
        if not args.quiet:
            print(limits_table(limits, indent="    "))
    return 2 if failed else 0


def profile_limits(profile: DutProfile) -> list[EffectiveLimit]:
    """The limits ``profile``'s DUT is judged against; the ISOBUS checks only for an ISOBUS
    implement (the only DUTs they are recorded for)."""
    limits = effective_limits(profile.dut.rig.replace("-", "_"), profile.limits)
    return [lim for lim in limits
            if profile.wiring.isobus or not lim.name.startswith("isobus.")]


def limits_table(limits: list[EffectiveLimit], *, indent: str = "") -> str:
    """The effective limits as aligned text: measurement, limit and unit, where it comes
    from (default from which standard, tightened, loosened with its reason, information)."""
    rows = [(lim.name, f"{lim.text} [{lim.unit}]" if lim.origin != "information" else "-",
             lim.describe()) for lim in limits]
    width = [max(len(r[0]) for r in rows),
             min(24, max(len(r[1]) for r in rows))]    # a long rule overflows its own row
    return "\n".join(f"{indent}{a:<{width[0]}}  {b:<{width[1]}}  {c}" for a, b, c in rows)


def _show(args: argparse.Namespace) -> int:
    profile = check_profile(args.file)
    out = {"identity": profile.identity(),
           "command": command_line(profile, bus=args.bus, clock=args.clock)
           if profile.launch.command else None,
           "inprocess": profile.launch.inprocess or None,
           "parameters": profile.parameters,
           "limits": [lim.to_dict() for lim in profile_limits(profile)]}
    print(json.dumps(out, indent=2))
    return 0


def _bind(args: argparse.Namespace) -> int:
    from hil.contract.bind import counts, write_binding

    database = Path(args.database)
    if not database.is_file():
        raise ConfigError(f"CAN database not found ({database.resolve()})",
                          path=str(database))
    contract = rig_contract(args.rig)
    output = Path(args.output) if args.output else None
    try:
        text = write_binding(database, contract,
                             relative_to=output.resolve().parent if output else Path.cwd())
    except FrameError as exc:
        raise ConfigError(str(exc), path=str(database)) from exc
    if output is None:
        sys.stdout.write(text)
    else:
        output.write_text(text, encoding="utf-8")
        bound, todo = counts(text)
        print(f"wrote {output}: {bound} quantities bound, {todo} TODO")
    return 0
