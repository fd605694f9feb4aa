"""From samples to statistics: per-measurement distributions, pass rates and the verdict."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hil.campaign.stats import clopper_pearson, lower_bound, verdict
from hil.gate.keys import measurement_key

#: sample verdicts that are a DUT result (the others are errors of the campaign's machinery or
#: of the bench, and are not counted in the pass rate)
JUDGED = ("pass", "fail")
BAD_OUTCOMES = ("fail", "error")


def badness(value: float | None, low: float | None, high: float | None) -> float:
    """How far ``value`` sits towards (or beyond) its limits: larger is worse; a missing value
    (not computed) is the worst of all."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return math.inf
    if low is not None and high is not None:
        return abs(value - 0.5 * (low + high)) - 0.5 * (high - low)
    if high is not None:
        return value - high
    if low is not None:
        return low - value
    return 0.0


def by_measurement(samples: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per measurement key: its identity and ``[(sample index, value, outcome)]``."""
    out: dict[str, dict[str, Any]] = {}
    for s in samples:
        if s["verdict"] not in JUDGED:
            continue
        for m in s["measurements"]:
            key = measurement_key(m["name"], m.get("conditions") or {})
            entry = out.setdefault(key, {"name": m["name"], "conditions": m.get("conditions")
                                         or {}, "unit": m.get("unit"), "low": m.get("low"),
                                         "high": m.get("high"), "points": []})
            entry["points"].append((s["index"], m.get("value"), m.get("outcome")))
    return out


def measurement_stats(entry: dict[str, Any], *, worst: int = 3,
                      confidence: float = 0.95) -> dict[str, Any]:
    """Mean, SD, min, max, pass rate with its exact interval and the worst samples."""
    points = entry["points"]
    values = np.array([np.nan if v is None else v for _, v, _ in points], dtype=float)
    finite = values[np.isfinite(values)]
    n = len(points)
    passed = sum(1 for _, _, o in points if o not in BAD_OUTCOMES)
    lo, hi = clopper_pearson(passed, n, confidence)
    ranked = sorted(points, key=lambda p: (-badness(p[1], entry["low"], entry["high"]), p[0]))
    return {
        "name": entry["name"], "conditions": entry["conditions"], "unit": entry["unit"],
        "low": entry["low"], "high": entry["high"], "n": n,
        "mean": _num(finite.mean()) if finite.size else None,
        "sd": _num(finite.std(ddof=1)) if finite.size > 1 else None,
        "min": _num(finite.min()) if finite.size else None,
        "max": _num(finite.max()) if finite.size else None,
        "not_computed": int(n - finite.size),
        "passed": passed, "failed": n - passed, "pass_rate": passed / n if n else None,
        "ci95": [lo, hi],
        "worst": [idx for idx, _, _ in ranked[:worst]],
    }


def summarize(samples: list[dict[str, Any]], *, pass_probability: float | None,
              confidence: float, worst: int = 3) -> dict[str, Any]:
    """The campaign summary and the per-measurement statistics."""
    judged = [s for s in samples if s["verdict"] in JUDGED]
    errors = [s for s in samples if s["verdict"] not in JUDGED]
    n, passed = len(judged), sum(1 for s in judged if s["verdict"] == "pass")
    v = verdict(passed, n, pass_probability=pass_probability, confidence=confidence,
                errors=len(errors))
    reason = v.reason
    cut = [s["index"] for s in errors if s["verdict"] == "interrupted"]
    if cut:
        # not a DUT result nor a failure of the DUT's run: the campaign did not run them
        reason += (f"; {len(cut)} of the samples not counted were interrupted (a worker "
                   f"stopped under them): the campaign was interrupted in part")
    lo, hi = clopper_pearson(passed, n, 0.95)
    measurements = {key: measurement_stats(entry, worst=worst)
                    for key, entry in sorted(by_measurement(samples).items())}
    return {
        "samples_done": len(samples), "judged": n, "passed": passed, "failed": n - passed,
        "errors": len(errors), "pass_rate": passed / n if n else None, "ci95": [lo, hi],
        "demonstrated_pass_probability": lower_bound(passed, n, confidence) if n else 0.0,
        "confidence": confidence, "required_pass_probability": pass_probability,
        "verdict": v.verdict, "reason": reason, "samples_needed": v.samples_needed,
        "failing_samples": sorted(s["index"] for s in judged if s["verdict"] == "fail"),
        "error_samples": sorted(s["index"] for s in errors),
    }, measurements


def _num(x: Any) -> float:
    return float(x)
