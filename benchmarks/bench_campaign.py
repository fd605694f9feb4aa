"""Campaign figures (issue 15): samples per minute on 1 and 2 local workers, per-sample cost
against one full qualification, worker RSS over the campaign.

    python benchmarks/bench_campaign.py --samples 300            # the issue's target run
    python benchmarks/bench_campaign.py --samples 40 --quick     # smaller N, extrapolated
    python benchmarks/bench_campaign.py --samples 300 --pair-samples 40   # the target, measured

Per-sample cost today against an earlier revision, side by side in one run (issue 29):

    python benchmarks/bench_campaign.py --rig depth --baseline 7700266 --samples 6

runs the same seeds one at a time (a campaign sample's pytest command: fast + robustness
suites, nominal rig, the Python reference controller in process on the inline bus, the
README's seeds), alternating between a git worktree of the baseline revision and this tree, and
prints each one's median CPU time per sample (user + system from getrusage: steadier than wall
time on a shared machine; a fresh interpreter per sample, as ``--isolation process``), the CPU
a 300-sample campaign on 2 cores takes at that rate, and whether both gave the same
measurements seed by seed. The baseline imports its own Python sources (PYTHONPATH) with this
tree's compiled twins, which it accepts only when their C sources are the same at both
revisions (a twin the baseline does not have is not copied).

Prints the figures; asserts nothing about time (figures, not tests). The machine's load average
is printed with them: on a shared machine the figures are only as good as that.

Per-sample figures, depth (``--rig depth --baseline 48723f1 --samples 5``, seeds
8700000-8700004, load average 3.8-4.4 on the 2-vCPU VM, so both figures are high): 48723f1
median 17.14 s of CPU per sample (min 15.50, max 18.57), this tree after issue 29's second
round 12.55 s (min 11.43, max 13.66; -27 %), every measurement the same seed by seed; 300
samples on 2 cores 42.9 -> 31.4 min of CPU. What the round took out: the runner no longer
hands frames to a recorder without bus log files; the depth controller's drive PDOs by one
``struct`` from canopen's maps (``reference_controllers/sowing_depth/pdo_struct.py``), its
plain frames without the typed dataclasses, its centroid's inner loop; the rig's drive TPDOs
framed by one ``struct`` of the drive's readers (``CanopenDevice.app_reader``); each EDS parsed
once per process (``canopen_device.object_dictionary``). The fertilizer sample is unchanged
(5.6-6.4 s, its measurements the same). Where a depth sample's CPU goes now (py-spy at
500 Hz, one sample): imports 21 % (scipy.signal ~10 %, python-control with matplotlib ~6 %,
through ``plant_emulators.sowing_depth.field`` and ``hil.metrics.step``), the controller under
test 21 % (its fuzzy inference 7 %), the rig's sensor, tractor, terminal and GNSS devices 16 %,
the runner's loop, barrier, bus and traces 14 %, the drive's CANopen node 12 %, the plant 8 %,
pytest and the rest 8 %: no one part is a quarter of it.
In this VM's environment (``PYTHONDONTWRITEBYTECODE=1``) a fresh interpreter also recompiles
and re-rewrites (pytest) every agrihil module it imports: ~0.75 s of a sample.

Third round (``--rig depth --baseline b2fdf79 --samples 5``, seeds 8700000-8700004, load
3.3-3.7): b2fdf79 median 10.92 s (min 10.67, max 11.42), this tree 8.89 s (min 8.64, max 9.17;
-19 %), every measurement the same seed by seed. Ten of a sample's 15 runs continue from the
checkpoint of an earlier run with the same prefix (``hil.rig.checkpoint``: the fault scenarios,
their twin and the drive's overcurrent up to 20 s, the step run's twin up to 15 s); this
benchmark counts the forked copies' CPU (each sample's process waits for them). A campaign's
forked samples also leave the fork server's objects out of garbage collection
(``hil.campaign.forked``), which a sample started here as a new interpreter does not show.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "dut_profiles/fertilizer-piecewise-pid-firmware.toml"
DAEMON = ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"
#: per rig: its reference profile in process (as the README's 300-sample campaigns) and seed
REFERENCE = {"fertilizer": ("dut_profiles/fertilizer-piecewise-pid-daemon.toml", 8500000),
             "depth": ("dut_profiles/sowing-depth-fuzzy-pid-daemon.toml", 8700000)}
RIG_SUITES = {"fertilizer": "fertilizer", "depth": "sowing_depth"}


def campaign(profile: Path, samples: int, workers: int, bus: str, out: Path,
             *extra: str) -> dict:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "hil", "campaign", str(profile), "--samples",
                    str(samples), "--workers", str(workers), "--bus", bus, "--out", str(out),
                    "--max-reruns", "0", "--no-progress", *extra], check=False,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    doc = json.loads((out / "campaign.json").read_text())
    doc["_wall"] = time.perf_counter() - t0
    return doc


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _baseline_tree(rev: str, where: Path) -> Path:
    """A worktree of ``rev`` at ``where`` with this tree's compiled twins copied in.

    Exits 2 naming the twin when its C sources differ between ``rev`` and this tree.
    """
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(where), rev],
                   check=True, stdout=subprocess.DEVNULL)
    for lib in ROOT.glob("plant_emulators/**/_*_native*.so"):
        package = lib.parent.relative_to(ROOT)
        if not (where / package / "native").is_dir():
            continue                        # a twin the baseline does not have
        same = subprocess.run(["git", "-C", str(ROOT), "diff", "--quiet", rev, "--",
                               str(package / "native"), "plant_emulators/native"],
                              check=False).returncode == 0
        if not same:
            raise SystemExit(f"bench_campaign: {package / 'native'} differs at {rev}: build "
                             f"the baseline's own twins to compare with it")
        shutil.copy2(lib, where / package / lib.name)
    return where


def _sample_cpu(root: Path, rig: str, profile: str, seed: int, out: Path) -> float:
    """CPU seconds (user + system) of one campaign sample of ``profile`` run from ``root``.

    The pytest command a campaign sample runs (``hil.campaign.sample.pytest_argv``, record
    ``measurements``), started here as a child so that its rusage is exact (a campaign's
    forked samples are reaped by Dask's fork servers, whose rusage never reaches this process).
    """
    suites = root / "test_suites"
    before = _children_cpu_s()
    subprocess.run([sys.executable, "-m", "pytest", str(suites / RIG_SUITES[rig]), "-c",
                    str(suites / "pytest.ini"), "--rootdir", str(suites / RIG_SUITES[rig]),
                    "-p", "no:cacheprovider", "-q", "--no-header", "--hil-dut",
                    str(root / profile), "--hil-bus", "inline", "--hil-clock", "lockstep",
                    "--hil-report", str(out), "--hil-suite", "fast,robustness", "--hil-seed",
                    str(seed), "--hil-record", "measurements", "-p", "no:hypothesispytest",
                    "-p", "no:benchmark"], check=False, cwd=root,
                   env={**os.environ, "PYTHONPATH": str(root), "PYTHONHASHSEED": "0"},
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return _children_cpu_s() - before


def paired(rig: str, rev: str, samples: int, base: Path) -> None:
    """Per-sample CPU of ``rig``'s reference campaign samples at ``rev`` and here, same seeds.

    The samples run one at a time, alternating between the trees (so that a change in the
    machine's load falls on both); each one's measurements are compared between the trees.
    """
    profile, seed = REFERENCE[rig]
    tree = base / "baseline"
    trees = {f"baseline {rev}": tree, "this tree": ROOT}
    cpu: dict[str, list[float]] = {label: [] for label in trees}
    differ = []
    try:
        _baseline_tree(rev, tree)
        for i in range(samples):
            values = []
            for label, root in trees.items():
                out = base / f"{label.replace(' ', '-')}-{i}"
                cpu[label].append(_sample_cpu(root, rig, profile, seed + i, out))
                record = json.loads((out / "record.json").read_text())
                values.append([(m["name"], m["conditions"], m["value"], m["outcome"])
                               for m in record["measurements"]])
            if values[0] != values[1]:
                differ.append(seed + i)
        for label, times in cpu.items():
            per = sorted(times)[len(times) // 2]
            print(f"{rig} reference sample (fast + robustness, inline, in process), {label}: "
                  f"median {per:.2f} s CPU over {len(times)} samples (min {min(times):.2f}, "
                  f"max {max(times):.2f}); 300 samples on 2 cores: "
                  f"{300 * per / 2 / 60:.1f} min of CPU")
        print(f"measurements seed by seed ({seed}-{seed + samples - 1}): "
              f"{'the same' if not differ else f'differ at seeds {differ}'}")
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                       check=False)


def qualify_s(profile: Path, bus: str, out: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "hil", "qualify", str(profile), "--bus", bus,
                    "--suite", "fast", "--out", str(out), "--quiet"], check=False,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--samples", type=int, default=300)
    parser.add_argument("--pair-samples", type=int, default=None,
                        help="samples of each 1-worker and 2-worker throughput run (default: "
                             "N, or N/2 with --quick)")
    parser.add_argument("--quick", action="store_true",
                        help="smaller throughput runs (N/2 samples) for the 1-vs-2 figure")
    parser.add_argument("--rig", choices=sorted(REFERENCE), default="fertilizer",
                        help="the rig of --baseline's paired figure")
    parser.add_argument("--baseline", metavar="REV", default=None,
                        help="only the per-sample CPU of --rig's reference campaign samples at "
                             "git revision REV beside this tree's (--samples seeds each)")
    args = parser.parse_args()
    n = args.samples
    print(f"load average at start: {os.getloadavg()}")
    if args.baseline is not None:
        with tempfile.TemporaryDirectory() as tmp:
            paired(args.rig, args.baseline, n, Path(tmp))
        print(f"load average at end: {os.getloadavg()}")
        return
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        single = {bus: qualify_s(p, bus, base / f"q-{bus}")
                  for bus, p in (("softbus", FIRMWARE), ("inline", DAEMON))}
        fw = campaign(FIRMWARE, n, 2, "softbus", base / "fw2")
        rate = len(fw["samples"]) / fw["_wall"] * 60
        per = [s["wall_s"] for s in fw["samples"] if s.get("wall_s")]
        rss = {s["index"]: s.get("rss_mb") for s in fw["samples"]}
        print(f"firmware fast suite, {n} samples on 2 workers (--isolation fork, the "
              f"default): {fw['_wall']:.0f} s "
              f"({rate:.1f} samples/min; 300 samples extrapolated: {300 / rate:.1f} min); "
              f"verdict {fw['summary']['verdict']} ({fw['summary']['passed']}/"
              f"{fw['summary']['judged']} passed)")
        print(f"per-sample wall (in its worker): median {sorted(per)[len(per) // 2]:.2f} s vs "
              f"one full qualification {single['softbus']:.2f} s (firmware, softbus)")
        print(f"worker RSS: sample 10: {rss.get(10)} MB, last sample {n - 1}: "
              f"{rss.get(n - 1)} MB")
        m = args.pair_samples or (max(4, n // 2) if args.quick else n)
        for bus, profile in (("inline", DAEMON), ("softbus", FIRMWARE)):
            one = campaign(profile, m, 1, bus, base / f"{bus}1")
            two = campaign(profile, m, 2, bus, base / f"{bus}2")
            r1, r2 = m / one["_wall"] * 60, m / two["_wall"] * 60
            print(f"{bus}: {m} samples, 1 worker {r1:.1f}/min, 2 workers {r2:.1f}/min: "
                  f"x{r2 / r1:.2f}")
        fresh = campaign(FIRMWARE, 6, 1, "softbus", base / "fw-process",
                         "--isolation", "process")
        per_fresh = sorted(s["wall_s"] for s in fresh["samples"])
        print(f"firmware per-sample wall median with --isolation process (a new interpreter "
              f"per sample) {per_fresh[len(per_fresh) // 2]:.2f} s")
        for isolation in ("fork", "process", "inprocess"):
            ins = campaign(DAEMON, 6, 1, "inline", base / f"in-cost-{isolation}",
                           "--isolation", isolation)
            per_in = sorted(s["wall_s"] for s in ins["samples"])
            print(f"inline per-sample wall median, --isolation {isolation}: "
                  f"{per_in[len(per_in) // 2]:.2f} s vs one full qualification "
                  f"{single['inline']:.2f} s")
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
