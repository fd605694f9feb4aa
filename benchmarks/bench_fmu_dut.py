"""Lockstep speed of an FMU DUT against the same firmware over the software bus (issue 40).

    python benchmarks/bench_fmu_dut.py                       # fertilizer, bench-step-23, 3 repeats
    python benchmarks/bench_fmu_dut.py --repeats 5 --rig depth --seconds 20

Runs one scenario in lockstep, in this process, against each of:

* the reference firmware as a process over the software bus (``*-firmware.toml``),
* its LS-BUS FMU on the inline bus (``*-fmu-lsbus.toml``), in its host process (the profile's
  default, ``[fmu] isolation = "process"``) and in this process (``isolation = "none"``), and
  on the software bus,
* (fertilizer) its signal-level FMU on the inline bus (``*-fmu-signal.toml``),

builds first (the profiles' [build], cached), then alternates the DUTs ``--repeats`` times and
prints, per DUT, the median wall time, the median CPU time of this process and its children
(user + system from getrusage: steadier than wall time on a shared machine) and the
simulated-to-wall ratio, and whether every run's bus log was the same bytes as the firmware's.
Prints the figures; asserts nothing about time (figures, not tests). The machine's load average
is printed with them: on a shared machine the figures are only as good as that.

Figures (2-core VM shared with other jobs, load average 18-21): fertilizer, 23 s simulated, 3
repeats: firmware over the software bus 2.49 s wall / 0.27 s CPU (x9.2), LS-BUS FMU inline
1.90 s / 0.22 s (x12.1), LS-BUS FMU on the software bus 2.97 s / 0.41 s (x7.7), signal-level
FMU inline 1.98 s / 0.22 s (x11.6), every bus log the firmware's (before the FMU host: the
FMUs in this process). Depth, 10 s of depth-step, 3 repeats, load average 13-15, two runs:
firmware over the software bus 4.79 / 2.56 s wall, 0.80 / 0.50 s CPU; LS-BUS FMU inline in its
host (isolation "process", the default) 7.84 / 4.39 s, 1.24 / 0.93 s; inline in this process
(isolation "none") 2.40 / 1.82 s, 0.50 / 0.42 s; on the software bus 3.44 / 3.89 s, 1.12 /
0.91 s; every bus log the firmware's.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hil.dut.factory import make_dut, profile_run_options  # noqa: E402
from hil.dut.profile import load_profile  # noqa: E402
from hil.rig.runner import RunOptions, run_scenario  # noqa: E402

RIGS = {
    "fertilizer": ("plant_emulators.fertilizer.rig:FertilizerRig", "bench-step-23", [
        ("firmware over softbus", "fertilizer-piecewise-pid-firmware", "softbus"),
        ("LS-BUS FMU, inline", "fertilizer-piecewise-pid-fmu-lsbus", "inline"),
        ("LS-BUS FMU, inline, no host", "fertilizer-piecewise-pid-fmu-lsbus", "inline/none"),
        ("LS-BUS FMU, softbus", "fertilizer-piecewise-pid-fmu-lsbus", "softbus"),
        ("signal-level FMU, inline", "fertilizer-piecewise-pid-fmu-signal", "inline")]),
    "depth": ("plant_emulators.sowing_depth.rig:SowingDepthRig", "depth-step", [
        ("firmware over softbus", "sowing-depth-fuzzy-pid-firmware", "softbus"),
        ("LS-BUS FMU, inline", "sowing-depth-fuzzy-pid-fmu-lsbus", "inline"),
        ("LS-BUS FMU, inline, no host", "sowing-depth-fuzzy-pid-fmu-lsbus", "inline/none"),
        ("LS-BUS FMU, softbus", "sowing-depth-fuzzy-pid-fmu-lsbus", "softbus")]),
}


def cpu_s() -> float:
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def run_once(rig_cls: type, scenario: str, seconds: float, profile_name: str, where: str,
             out: Path) -> tuple[float, float, bytes]:
    """One run; ``where`` is the bus, or ``bus/isolation`` for an FMU's ``[fmu] isolation``."""
    bus, _, isolation = where.partition("/")
    profile = load_profile(ROOT / "dut_profiles" / f"{profile_name}.toml")
    if isolation and profile.fmu is not None:
        profile = dataclasses.replace(profile, fmu=dataclasses.replace(profile.fmu,
                                                                       isolation=isolation))
    dut, _ = make_dut(profile, bus=bus, clock="lockstep", log_dir=out)
    sc = dataclasses.replace(rig_cls.load_scenario(scenario), duration_s=seconds)
    c0, t0 = cpu_s(), time.perf_counter()
    result = run_scenario(rig_cls, sc, dut, RunOptions(out_dir=out, bus=bus, clock="lockstep",
                                                       **profile_run_options(profile)))
    wall, cpu = time.perf_counter() - t0, cpu_s() - c0
    if result.record.get("error"):
        raise SystemExit(f"{profile_name} on {bus}: {result.record['error']}")
    return wall, cpu, (out / "bus.log").read_bytes()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rig", choices=sorted(RIGS), default="fertilizer")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=None,
                        help="simulated seconds (default: the scenario's)")
    args = parser.parse_args()
    target, scenario, duts = RIGS[args.rig]
    module, _, name = target.partition(":")
    rig_cls = getattr(__import__(module, fromlist=[name]), name)
    seconds = args.seconds or rig_cls.load_scenario(scenario).duration_s
    walls: dict[str, list[float]] = {label: [] for label, _, _ in duts}
    cpus: dict[str, list[float]] = {label: [] for label, _, _ in duts}
    same: dict[str, bool] = {label: True for label, _, _ in duts}
    with tempfile.TemporaryDirectory(prefix="bench-fmu-") as tmp:
        for _label, profile, bus in duts:      # builds (cached) and warms up, not timed
            run_once(rig_cls, scenario, 1.0, profile, bus,
                     Path(tmp) / f"warm-{profile}-{bus.replace('/', '-')}")
        for i in range(args.repeats):
            reference = b""
            for label, profile, bus in duts:
                wall, cpu, log = run_once(rig_cls, scenario, seconds, profile, bus,
                                          Path(tmp) / f"{i}-{profile}-{bus.replace('/', '-')}")
                walls[label].append(wall)
                cpus[label].append(cpu)
                reference = reference or log
                same[label] &= log == reference
    print(f"{args.rig}: {scenario}, {seconds:g} s simulated, lockstep, {args.repeats} repeats; "
          f"load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"{'DUT':28} {'wall s':>8} {'CPU s':>8} {'x real time':>12}  bus log = firmware's")
    for label, _, _ in duts:
        wall = statistics.median(walls[label])
        cpu = statistics.median(cpus[label])
        print(f"{label:28} {wall:8.2f} {cpu:8.2f} {seconds / wall:12.1f}  {same[label]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
