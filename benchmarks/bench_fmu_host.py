"""What the FMU host costs: an FMU DUT in a process of its own against the same FMU in the rig's.

    python benchmarks/bench_fmu_host.py                 # fertilizer, bench-step-23, 3 repeats
    python benchmarks/bench_fmu_host.py --repeats 5 --seconds 10

Runs the fertilizer's ``bench-step-23`` in lockstep on the inline bus, in this process, against
the reference controller's LS-BUS FMU and its signal-level FMU, each with ``[fmu] isolation =
"process"`` (the FMU host: one pipe round trip per frame the rig sends) and ``"none"`` (the
FMU in the rig's process), alternating them ``--repeats`` times after a warm-up (the builds are
cached). Prints per DUT the median wall time, the median CPU time of this process and its
children (the hosts, each waited for when its run ends; user + system from getrusage), the
simulated-to-wall ratio, the frames that crossed to the host per run, and whether every run's
bus log was the same bytes as the in-process run's. Asserts nothing about time (figures, not
tests); prints the load average with them.

Figures (2-core host shared with other jobs, load average 12-15; 3 repeats): LS-BUS FMU
in process 0.81 s wall / 0.18 s CPU, in its host 1.49 s / 0.35 s (2,334 round trips); signal-
level FMU in process 0.97 s / 0.19 s, in its host 1.50 s / 0.24 s (234 round trips); every
bus log the in-process run's. docs/guide/fmu-controller.md, "Isolation: the FMU host".
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
from hil.dut.profile import DutProfile, load_profile  # noqa: E402
from hil.rig.runner import RunOptions, run_scenario  # noqa: E402
from plant_emulators.fertilizer.rig import FertilizerRig  # noqa: E402

SCENARIO = "bench-step-23"
PROFILES = (("LS-BUS FMU", "fertilizer-piecewise-pid-fmu-lsbus"),
            ("signal-level FMU", "fertilizer-piecewise-pid-fmu-signal"))
ISOLATIONS = ("none", "process")


def cpu_s() -> float:
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def profile_with(name: str, isolation: str) -> DutProfile:
    profile = load_profile(ROOT / "dut_profiles" / f"{name}.toml")
    assert profile.fmu is not None
    return dataclasses.replace(profile, fmu=dataclasses.replace(profile.fmu,
                                                                isolation=isolation))


def run_once(profile: DutProfile, seconds: float, out: Path) -> tuple[float, float, bytes, int]:
    dut, _ = make_dut(profile, bus="inline", clock="lockstep", log_dir=out)
    sc = dataclasses.replace(FertilizerRig.load_scenario(SCENARIO), duration_s=seconds)
    c0, t0 = cpu_s(), time.perf_counter()
    result = run_scenario(FertilizerRig, sc, dut, RunOptions(
        out_dir=out, bus="inline", clock="lockstep", **profile_run_options(profile)))
    wall, cpu = time.perf_counter() - t0, cpu_s() - c0
    if result.record.get("error"):
        raise SystemExit(f"{profile.name}: {result.record['error']}")
    calls = int(result.record["dut"]["fmu_isolation"].get("round_trips") or 0)
    return wall, cpu, (out / "bus.log").read_bytes(), calls


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=None,
                        help="simulated seconds (default: the scenario's)")
    args = parser.parse_args()
    seconds = args.seconds or FertilizerRig.load_scenario(SCENARIO).duration_s
    duts = [(f"{label}, {isolation}", profile_with(name, isolation), name)
            for label, name in PROFILES for isolation in ISOLATIONS]
    walls: dict[str, list[float]] = {label: [] for label, _, _ in duts}
    cpus: dict[str, list[float]] = {label: [] for label, _, _ in duts}
    calls: dict[str, int] = {}
    same: dict[str, bool] = {label: True for label, _, _ in duts}
    with tempfile.TemporaryDirectory(prefix="bench-fmu-host-") as tmp:
        for label, profile, _ in duts:           # builds (cached) and warms up, not timed
            run_once(profile, 1.0, Path(tmp) / f"warm-{label}")
        for i in range(args.repeats):
            in_process: dict[str, bytes] = {}
            for label, profile, name in duts:
                wall, cpu, log, n = run_once(profile, seconds, Path(tmp) / f"{i}-{label}")
                walls[label].append(wall)
                cpus[label].append(cpu)
                calls[label] = n
                reference = in_process.setdefault(name, log)
                same[label] &= log == reference
    print(f"fertilizer: {SCENARIO}, {seconds:g} s simulated, lockstep, inline bus, "
          f"{args.repeats} repeats; load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"{'DUT, isolation':28} {'wall s':>8} {'CPU s':>8} {'x real time':>12} "
          f"{'round trips':>12}  bus log = in-process")
    for label, _, _ in duts:
        wall = statistics.median(walls[label])
        cpu = statistics.median(cpus[label])
        print(f"{label:28} {wall:8.2f} {cpu:8.2f} {seconds / wall:12.1f} "
              f"{calls.get(label, 0):12d}  {same[label]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
