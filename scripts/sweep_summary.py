"""Summarise a campaign's ``samples.jsonl``: pass rate with its Clopper-Pearson bound, the
failures, each measurement's seed-to-seed spread and its closest approach to its limit.

Usage::

    python scripts/sweep_summary.py campaign/samples.jsonl [--tolerances ci/tolerances.toml]

With ``--tolerances`` it also prints, for every measurement the bands name, the band beside the
seed-to-seed standard deviation (a band narrower than the spread flags noise, not regressions,
when a controller change reshuffles the noise a run sees).
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from collections import defaultdict
from fnmatch import fnmatchcase
from pathlib import Path

import numpy as np
from scipy.stats import beta


def clopper_pearson_lower(passes: int, n: int, confidence: float = 0.95) -> float:
    """One-sided lower bound of the pass probability at ``confidence``.

    Parameters
    ----------
    passes : int
        Runs that passed.
    n : int
        Runs in all.
    confidence : float
        One-sided confidence level.

    Returns
    -------
    float
        The Clopper-Pearson lower bound (0 when ``passes`` is 0).
    """
    if passes == 0:
        return 0.0
    return float(beta.ppf(1.0 - confidence, passes, n - passes + 1))


def _key(m: dict) -> str:
    cond = ",".join(f"{k}={v}" for k, v in sorted((m.get("conditions") or {}).items()))
    return f"{m['name']}[{cond}]" if cond else m["name"]


def _band(tolerances: dict, name: str) -> dict | None:
    exact = tolerances.get("measurements", {})
    if name in exact:
        return exact[name]
    globs = [(g, b) for g, b in exact.items() if any(c in g for c in "*?[")
             and fnmatchcase(name, g)]
    if globs:
        return max(globs, key=lambda gb: len(gb[0].replace("*", "")))[1]
    return tolerances.get("default")


def main(argv: list[str] | None = None) -> int:
    """Print the summary of one or more sweep files."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweeps", nargs="+", type=Path)
    ap.add_argument("--tolerances", type=Path)
    args = ap.parse_args(argv)
    rows = []
    for path in args.sweeps:
        try:
            lines = path.read_text().splitlines()
        except OSError as exc:
            print(f"sweep_summary: cannot read {path}: {exc.strerror}", file=sys.stderr)
            return 2
        for number, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                rows.append(json.loads(line))
            except ValueError as exc:
                print(f"sweep_summary: {path}:{number}: not a JSON sample ({exc})",
                      file=sys.stderr)
                return 2
    rows = [r for r in rows if r.get("verdict") is not None]
    n = len(rows)
    passes = sum(r["verdict"] == "pass" for r in rows)
    print(f"{n} seeds, {passes} pass, {n - passes} not; pass probability >= "
          f"{clopper_pearson_lower(passes, n):.3f} at 95 % confidence (Clopper-Pearson)")
    values: dict[str, list[float]] = defaultdict(list)
    margin: dict[str, tuple[float, int, float, str]] = {}
    for r in rows:
        for m in r["measurements"]:
            key = _key(m)
            if m["outcome"] not in ("pass", "info", "marginal"):
                note = m.get("note") or ""
                print(f"  seed {r['seed']}: {key} = {m['value']} {m['outcome']} {note}")
            v = m["value"]
            if v is None:
                continue
            values[key].append(float(v))
            for lim, sign in ((m.get("high"), 1.0), (m.get("low"), -1.0)):
                if lim is None:
                    continue
                room = sign * (lim - float(v))
                if key not in margin or room < margin[key][0]:
                    side = "high" if sign > 0 else "low"
                    margin[key] = (room, r["seed"], float(v), f"{side} {lim}")
    print("closest to the limit (margin = room left, in the measurement's unit):")
    for key, (room, seed, v, lim) in sorted(margin.items(), key=lambda kv: kv[1][0]):
        vals = np.array(values[key])
        print(f"  {key}: worst {v:.4g} at seed {seed} ({lim}), margin {room:.4g}; "
              f"mean {vals.mean():.4g} sd {vals.std(ddof=1) if len(vals) > 1 else 0:.3g}")
    if args.tolerances:
        tol = tomllib.loads(args.tolerances.read_text())
        print("tolerance band vs seed-to-seed spread (sd):")
        for key, vals in sorted(values.items()):
            name = key.split("[", 1)[0]
            band = _band(tol, name)
            if band is None or len(vals) < 2:
                continue
            arr = np.array(vals)
            width = max(band.get("abs", 0.0), band.get("rel", 0.0) * abs(float(np.median(arr))))
            sd = float(arr.std(ddof=1))
            flag = "  <-- band narrower than the spread" if width < sd else ""
            print(f"  {key}: band {width:.3g}, sd {sd:.3g}{flag}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
