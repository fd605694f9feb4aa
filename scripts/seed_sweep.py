"""Qualify a reference profile over many fresh seeds and keep one JSON line per seed.

A stop-gap for issue #16's evidence until the campaign command exists: it runs
``hil qualify PROFILE --bus inline --seed N`` for each seed with a few processes at a time,
appends the verdict and every measurement to a JSON-lines file, and keeps the output
directory (traces) only for seeds that did not pass.

Usage::

    python scripts/seed_sweep.py dut_profiles/fertilizer-piecewise-pid-daemon.toml \
        --first 500000 --count 300 --jobs 2 --out /tmp/sweep_fert
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path


def qualify_one(profile: str, seed: int, out_root: Path, bus: str, suites: str) -> dict:
    """Run one qualification and summarise its record.

    Parameters
    ----------
    profile : str
        The DUT profile to qualify.
    seed : int
        The seed passed to ``hil qualify --seed``.
    out_root : Path
        Directory under which ``q_<seed>`` is written.
    bus : str
        The ``--bus`` spec.
    suites : str
        The ``--suite`` value.

    Returns
    -------
    dict
        ``seed``, ``verdict``, ``exit`` and ``measurements`` (name, conditions, value, outcome,
        low, high, note).
    """
    out = out_root / f"q_{seed}"
    cmd = ["hil", "qualify", profile, "--bus", bus, "--seed", str(seed), "--suite", suites,
           "--out", str(out), "--quiet"]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    row: dict = {"seed": seed, "exit": proc.returncode, "verdict": None, "measurements": []}
    try:
        record = json.loads((out / "record.json").read_text())
    except (OSError, ValueError) as exc:
        row["error"] = f"no record: {exc}; stderr tail: {proc.stderr[-400:]}"
        return row
    row["verdict"] = record.get("verdict")
    row["measurements"] = [
        {k: m.get(k) for k in ("name", "conditions", "value", "outcome", "low", "high", "note")}
        for m in record.get("measurements", [])
    ]
    if row["verdict"] == "pass":
        shutil.rmtree(out, ignore_errors=True)
    return row


def main(argv: list[str] | None = None) -> int:
    """Parse the options, run the seeds and append their summaries."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("profile")
    ap.add_argument("--first", type=int, required=True, help="first seed")
    ap.add_argument("--count", type=int, required=True, help="number of seeds")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--bus", default="inline")
    ap.add_argument("--suite", default="fast,robustness")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    lines = args.out / "sweep.jsonl"
    seeds = range(args.first, args.first + args.count)
    with ThreadPoolExecutor(args.jobs) as pool, lines.open("a") as fh:
        futures = [pool.submit(qualify_one, args.profile, s, args.out, args.bus, args.suite)
                   for s in seeds]
        for fut in futures:
            row = fut.result()
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            bad = [m["name"] for m in row["measurements"] if m["outcome"] not in ("pass", "info")]
            print(row["seed"], row["verdict"], bad, file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
