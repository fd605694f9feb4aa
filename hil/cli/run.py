"""``hil run``: run one scenario of a rig against a DUT and record it.

    hil run --rig fertilizer --list-scenarios
    hil run --rig fertilizer --dut builtin:pi --scenario bench-step --out runs/step --plot
    hil run --dut dut_profiles/fertilizer-piecewise-pid-daemon.toml --scenario field-6kmh

With a DUT profile the rig comes from the profile (``--rig`` may be left out) and the DUT is
built (firmware, cached), started, watched and stopped as the profile says.

The run writes into ``--out`` as ``hil qualify`` does (:mod:`hil.record.staging`): every option
is checked and the DUT built and found executable before ``--out`` is touched (a run refused
at setup leaves it as it was); the run then records into a hidden staging directory inside
``--out`` while ``record.json`` says it has not finished (the previous one kept as
``record.previous.json``), and its files move in when it ends, the record last. A disk that
refuses a write (full, file size limit) is exit 2 naming the path, with the staging removed
and the previous run's files left as they were; a half-written run never lands in ``--out``.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hil.cli.args import (
    add_bus_clock,
    check_bus_for_dut,
    check_bus_spec,
    check_launchable,
    check_positive_seconds,
    check_seed,
    prepare_out_dir,
)
from hil.cli.phases import phase
from hil.dut import DutRunner, InProcessDut
from hil.dut.build import with_build_id
from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import DutProfile, load_profile
from hil.errors import ConfigError, HilError
from hil.ownrig.cli_support import check_profile_rig, register_option_rig
from hil.record.atomic import write_json_atomic
from hil.record.staging import Staging, signals_held
from hil.rig import Rig, RunOptions, available_rigs, load_rig, run_scenario
from hil.rig.runner import RunResult, check_events, check_run
from hil.rig.scenario import Scenario
from hil.validation import help_with_range, option_type

#: the staging directory's prefix inside --out (followed by the process id)
STAGING_PREFIX = ".run-"
RECORD = "record.json"


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    run = subparsers.add_parser("run", help="run one scenario of a rig against a DUT")
    run.add_argument("--rig", help=f"rig name ({', '.join(available_rigs())}) or a rig file "
                                   "(a rig of your own: its .toml file); taken from the "
                                   "profile when --dut is one")
    run.add_argument("--list-scenarios", action="store_true",
                     help="print the rig's scenarios, one per line, and exit")
    run.add_argument("--dut", help="the controller under test: a DUT profile (TOML) or "
                                   "builtin:NAME (a minimal controller the rig ships)")
    run.add_argument("--scenario", help="scenario name (see --list-scenarios) or a TOML file")
    add_bus_clock(run)
    run.add_argument("--out", default=None, help="output directory (default runs/<scenario>)")
    run.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    run.add_argument("--plot", action="store_true", help="save plot.png of the main signals")
    run.add_argument("--csv", action="store_true", help="also write traces.csv")
    run.add_argument("--build-id", default=None,
                     help="with a DUT profile: its build id for the record (a CI job passes "
                          "its commit); default: the profile's [dut] build_id")
    run.add_argument("--step-timeout", type=option_type("run --step-timeout"), default=2.0,
                     help=help_with_range("run --step-timeout",
                                          "lockstep: seconds to wait for the DUT's answer to "
                                          "SYNC (default: 2)"))
    run.set_defaults(func=_run)


def _builtin_dut(rig_cls: type[Rig], dut: str) -> InProcessDut:
    kind, _, name = dut.partition(":")
    builtins = rig_cls.builtin_controllers()
    if kind == "builtin" and name in builtins:
        return InProcessDut(builtins[name]())  # type: ignore[arg-type]
    if kind == "builtin":
        raise ConfigError(f"rig {rig_cls.name} has no built-in controller {name!r}; available: "
                          f"{', '.join('builtin:' + n for n in builtins)}", key="dut")
    raise ConfigError(f"unsupported DUT {dut!r}: give a DUT profile (.toml) or builtin:NAME "
                      f"({', '.join('builtin:' + n for n in builtins)})", key="dut")


def _is_profile(dut: str | None) -> bool:
    return bool(dut) and not str(dut).startswith("builtin:")


def _run(args: argparse.Namespace) -> int:
    # options first: a bad one is exit 2 before anything is built or started
    check_seed(args.seed)
    check_positive_seconds(args.step_timeout, "--step-timeout")
    check_bus_spec(args.bus)
    if args.bus == "inline" and args.clock != "lockstep":
        raise ConfigError("the inline bus calls the controller inside the lockstep loop: use "
                          "--clock lockstep, or a bus (softbus) for real time", key="--bus")
    own_rig = register_option_rig(args.rig)     # a rig file: known before a profile names it
    profile = load_profile(args.dut) if _is_profile(args.dut) else None
    if profile is not None:
        check_profile_rig(own_rig, profile)
        from hil.cli.profile import refuse_problems

        refuse_problems(profile)                   # what `hil profile check` would report
    if args.build_id is not None:
        if profile is None:
            raise ConfigError("--build-id needs a DUT profile as --dut (a builtin has none)",
                              key="build_id")
        profile = with_build_id(profile, args.build_id)
    if profile is not None:
        check_bus_for_dut(args.bus, profile.dut.kind,
                          inprocess_twin=bool(profile.launch.inprocess))
    rig_name = args.rig or (profile.dut.rig if profile else None)
    if rig_name is None:
        print("hil: error: --rig is needed (or a DUT profile as --dut)", file=sys.stderr)
        return 2
    if profile is not None and args.rig and load_rig(args.rig) is not load_rig(profile.dut.rig):
        raise ConfigError(f"--rig {args.rig} but the profile is wired to {profile.dut.rig}",
                          path=str(profile.path), key="dut.rig")
    rig_cls = load_rig(rig_name)
    if args.list_scenarios:
        for name, description in rig_cls.scenario_names():
            print(f"{name}  {description}")
        return 0
    if not args.scenario or not args.dut:
        print("hil: error: --scenario and --dut are needed (or --list-scenarios)",
              file=sys.stderr)
        return 2
    scenario = rig_cls.load_scenario(args.scenario)
    if str(args.scenario).endswith(".toml"):
        check_events(scenario, path=str(args.scenario))
    out = Path(args.out or f"runs/{scenario.name}")
    check_run(scenario, RunOptions(out_dir=out, seed=args.seed,
                                   step_timeout_s=args.step_timeout))
    prepare_out_dir(out)
    staging = Staging(out, prefix=STAGING_PREFIX, outputs=None, record=RECORD)
    # the DUT is built and its command checked before --out is touched; its output goes to
    # the staging directory with the rest of the run
    dut, extra, from_profile = _make_dut(args, profile, rig_cls, staging.path)
    try:
        phase("run:built")
        # from here on record.json says this run has not finished until it has (the previous
        # one kept as record.previous.json); a signal during begin() arrives right after it
        staging.begin(_unfinished(staging, rig_cls, scenario, args,
                                  "the run started and has not finished (or was killed)"))
    except KeyboardInterrupt:
        if not staging.path.exists():
            print("hil: interrupted before the run began; --out is untouched",
                  file=sys.stderr)
            return 130
        _finish(staging, rig_cls, scenario, args)
        raise
    print(f"hil: running {rig_cls.name}/{scenario.name} ({scenario.duration_s:g} s, "
          f"{args.clock}) against {args.dut} on {args.bus}", file=sys.stderr)
    try:
        phase("run:staged")
        with _named_in_out(staging), staging.writing():   # a refused write: no staging left
            result = run_scenario(rig_cls, scenario, dut,
                                  RunOptions(out_dir=staging.path, clock=args.clock,
                                             bus=args.bus, seed=args.seed, csv=args.csv,
                                             step_timeout_s=args.step_timeout,
                                             extra_meta=extra, **from_profile))
            _refuse_unwritten(result, staging)
            if args.plot:
                _plot(rig_cls, scenario, args, staging.path)
            phase("run:written")
    finally:
        # whatever ended the run after it began (an interruption, the DUT, the bus), what it
        # recorded moves in: its record says why
        if staging.path.exists():
            _finish(staging, rig_cls, scenario, args)
    return _summary(result, out)


@contextlib.contextmanager
def _named_in_out(staging: Staging) -> Iterator[None]:
    """An error that names a file of the staging directory names it where it will be: the
    run's files move into ``--out`` however the run ends (a physical ECU's endpoints file, a
    DUT's log)."""
    try:
        yield
    except HilError as exc:
        if str(staging.path) not in str(exc):
            raise
        raise HilError(str(exc).replace(str(staging.path), str(staging.out))) from exc


def _make_dut(args: argparse.Namespace, profile: DutProfile | None, rig_cls: type[Rig],
              log_dir: Path) -> tuple[DutRunner, dict[str, object], dict[str, Any]]:
    """The DUT runner (a profile's DUT built, cached, and its command checked: a DUT that
    cannot start is a setup error before the run), the record's facts of it and the run
    options the profile sets."""
    if profile is None:
        return _builtin_dut(rig_cls, args.dut), {}, {}
    dut, build = make_dut(profile, bus=args.bus, clock=args.clock, log_dir=log_dir)
    build_dir = build.get("build_dir") if build else None
    check_launchable(profile, bus=args.bus, clock=args.clock,
                     build=Path(str(build_dir)) if build_dir else None)
    return (dut, {"dut_identity": profile.identity(), "dut_build": build},
            profile_run_options(profile))


def _unfinished(staging: Staging, rig_cls: type[Rig], scenario: Scenario,
                args: argparse.Namespace, why: str) -> dict[str, Any]:
    """A run record saying the run did not finish (verdict ``aborted``), naming no file."""
    return {"run_id": staging.run_id,
            "started_at": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            "verdict": "aborted", "error": why, "complete": False, "rig": rig_cls.name,
            "scenario": scenario.name, "clock": args.clock, "bus": args.bus,
            "seeds": {} if args.seed is None else {"scenario": args.seed},
            "measurements": [], "artifacts": [RECORD], "command": sys.argv}


def _finish(staging: Staging, rig_cls: type[Rig], scenario: Scenario,
            args: argparse.Namespace) -> None:
    """Move the staged run into ``--out``, the record last, signals held. When the run wrote
    no record (interrupted before it started, or while the recorder wrote), one saying so."""
    with signals_held(), staging.writing():
        if not (staging.path / RECORD).exists():
            write_json_atomic(staging.path / RECORD, _unfinished(
                staging, rig_cls, scenario, args,
                "interrupted before the run's record was written; its files may be missing "
                "or incomplete"))
        phase("run:promote")            # held: arrives once the run is in
        staging.promote()


def _refuse_unwritten(result: RunResult, staging: Staging) -> None:
    """A run whose traces or bus logs could not all be written is not a run: the recorder
    noted why in its record (and wrote that); the staging is removed and the command fails
    naming ``--out``, instead of promoting truncated files under a verdict."""
    problems = result.record.get("recorder_problems")
    if not problems:
        return
    staging.discard()
    raise HilError(f"{staging.out}: the run's files could not all be written "
                   f"({'; '.join(map(str, problems))}); nothing of this run was kept")


def _plot(rig_cls: type[Rig], scenario: Scenario, args: argparse.Namespace,
          run_dir: Path) -> None:
    from hil.plot import plot_traces
    from hil.record import load_traces

    arrays, units = load_traces(run_dir / "traces.npz")
    plot_traces(arrays, units, rig_cls.plot_groups, run_dir / "plot.png",
                f"{rig_cls.name} / {scenario.name} ({args.clock}, {args.dut})")


def _summary(result: RunResult, out: Path) -> int:
    record = result.record
    timing = record.get("timing") or {}
    print(f"hil: {record['verdict']}: {result.sim_s:.1f} s simulated in {result.wall_s:.2f} s "
          f"(x{result.realtime_factor:,.0f}); wrote {out}/", file=sys.stderr)
    if timing.get("mode") == "realtime":
        print(f"hil: timing: lateness p50 {timing['lateness_p50_s'] * 1e6:.0f} us, p99 "
              f"{timing['lateness_p99_s'] * 1e6:.0f} us, max "
              f"{timing['lateness_max_s'] * 1e6:.0f} us, {timing['misses']} misses, "
              f"{timing['scheduler']}", file=sys.stderr)
    if record["error"]:
        print(f"hil: run failed: {record['error']}", file=sys.stderr)
        return 1
    return 1 if record["verdict"] == "invalid-bench" else 0
