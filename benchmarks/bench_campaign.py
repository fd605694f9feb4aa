"""Campaign figures (issue 15): samples per minute on 1 and 2 local workers, per-sample cost
against one full qualification, worker RSS over the campaign.

    python benchmarks/bench_campaign.py --samples 300            # the issue's target run
    python benchmarks/bench_campaign.py --samples 40 --quick     # smaller N, extrapolated
    python benchmarks/bench_campaign.py --samples 300 --pair-samples 40   # the target, measured

Prints the figures; asserts nothing about time (figures, not tests). The machine's load average
is printed with them: on a shared machine the figures are only as good as that.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIRMWARE = ROOT / "dut_profiles/fertilizer-piecewise-pid-firmware.toml"
DAEMON = ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"


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
    args = parser.parse_args()
    n = args.samples
    print(f"load average at start: {os.getloadavg()}")
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
