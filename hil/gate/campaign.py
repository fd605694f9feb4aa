"""The campaign gate: a campaign record against a campaign baseline, by distribution.

For each measurement (name + conditions) both campaigns measured, the values are turned into
"how bad" (larger is worse: the value itself under a high limit, its negative over a low one,
the distance from the middle between two limits) and the mean shift ``d`` of the new campaign
over the baseline is tested against the band ``theta = shift_fraction x band`` (the tolerance
file's band for that measurement, as for single qualifications) with a one-sided Welch t-test of
``d > theta``. A regression is a shift the test finds beyond ``theta`` at ``alpha`` divided by
the number of measurements compared (Bonferroni): seed noise moves a mean by its standard error,
and the test accounts for it, so two campaigns of the same build do not flag each other.

The band of a single-sample gate must hold one sample's seed noise (about 2.5 standard deviations
of it for the field accuracy: a 1.0 point band over a ~0.4 point sample SD) as well as the
legitimate change of a new build; a campaign's mean has no seed noise left to absorb, so only
the legitimate-change part remains: ``shift_fraction`` (default 0.25) of the band.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import t as student_t

from hil.gate.keys import measurement_key
from hil.gate.tolerance import DEFAULT_TOLERANCES, Tolerances

ALPHA = 0.01
SHIFT_FRACTION = 0.25


@dataclass(frozen=True)
class ShiftRow:
    """One measurement's comparison."""

    key: str
    name: str
    status: str             # ok | regression | improved | missing | no-direction
    n: int = 0
    n_base: int = 0
    mean: float | None = None
    mean_base: float | None = None
    #: mean shift in the worse direction (positive: worse), and the band it is tested against
    shift: float | None = None
    threshold: float | None = None
    p_value: float | None = None


@dataclass
class CampaignGateResult:
    verdict: str            # pass | fail | error
    campaign_verdict: str
    rows: list[ShiftRow] = field(default_factory=list)
    alpha: float = ALPHA
    notes: list[str] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        return {"pass": 0, "fail": 1}.get(self.verdict, 2)

    @property
    def regressions(self) -> list[ShiftRow]:
        return [r for r in self.rows if r.status in ("regression", "missing")]


def _values(doc: dict[str, Any]) -> dict[str, tuple[dict[str, Any], list[float]]]:
    out: dict[str, tuple[dict[str, Any], list[float]]] = {}
    for s in doc["samples"]:
        if s["verdict"] not in ("pass", "fail"):
            continue
        for m in s["measurements"]:
            key = measurement_key(m["name"], m.get("conditions") or {})
            value = m.get("value")
            entry = out.setdefault(key, (m, []))
            entry[1].append(math.nan if value is None else float(value))
    return out


def worseness(values: list[float], low: float | None, high: float | None) -> np.ndarray | None:
    """Values as "how bad" (larger is worse), or None when the limits give no direction."""
    x = np.asarray(values, dtype=float)
    if low is not None and high is not None:
        return np.abs(x - 0.5 * (low + high))
    if high is not None:
        return x
    if low is not None:
        return -x
    return None


def welch_shift_p(new: np.ndarray, base: np.ndarray, threshold: float) -> float:
    """One-sided p-value of ``mean(new) - mean(base) > threshold`` (Welch's t-test)."""
    n1, n2 = new.size, base.size
    d = float(new.mean() - base.mean())
    v1 = float(new.var(ddof=1)) / n1 if n1 > 1 else 0.0
    v2 = float(base.var(ddof=1)) / n2 if n2 > 1 else 0.0
    se2 = v1 + v2
    if se2 == 0.0:
        return 0.0 if d > threshold else 1.0
    df = se2 ** 2 / ((v1 ** 2 / (n1 - 1) if n1 > 1 else 0.0)
                     + (v2 ** 2 / (n2 - 1) if n2 > 1 else 0.0))
    return float(student_t.sf((d - threshold) / math.sqrt(se2), df))


def compare_campaigns(record: dict[str, Any], baseline: dict[str, Any] | None,
                      tolerances: Tolerances = DEFAULT_TOLERANCES, *, alpha: float = ALPHA,
                      shift_fraction: float = SHIFT_FRACTION,
                      allow_regressions: bool = False) -> CampaignGateResult:
    """Gate a campaign: its own verdict, then (with a baseline) the shift of every mean."""
    own = record["summary"]["verdict"]
    result = CampaignGateResult(verdict="pass", campaign_verdict=own, alpha=alpha)
    if own == "error":
        result.verdict = "error"
        result.notes.append("the campaign has no verdict (no sample completed)")
        return result
    if own in ("fail", "inconclusive"):
        result.verdict = "fail"
        result.notes.append(f"the campaign itself is {own}: {record['summary']['reason']}")
    if record.get("status") != "complete":
        result.notes.append(f"the campaign is {record.get('status')}: "
                            f"{len(record['samples'])} of {record['samples_requested']} samples")
    if baseline is None:
        return result
    if baseline["dut"].get("name") != record["dut"].get("name"):
        result.notes.append(f"baseline of {baseline['dut'].get('name')}, record of "
                            f"{record['dut'].get('name')}")
    new, base = _values(record), _values(baseline)
    compared = [k for k in base if k in new]
    corrected = alpha / max(1, len(compared))
    for key in sorted(set(base) | set(new)):
        if key not in new:
            result.rows.append(ShiftRow(key, base[key][0]["name"], "missing",
                                        n_base=len(base[key][1])))
            continue
        if key not in base:
            continue
        meta, values = new[key]
        w_new = worseness(values, meta.get("low"), meta.get("high"))
        w_base = worseness(base[key][1], meta.get("low"), meta.get("high"))
        mean, mean_base = _mean(values), _mean(base[key][1])
        if w_new is None or w_base is None:
            result.rows.append(ShiftRow(key, meta["name"], "no-direction", len(values),
                                        len(base[key][1]), mean, mean_base))
            continue
        if np.isnan(w_new).any() and not np.isnan(w_base).any():
            result.rows.append(ShiftRow(key, meta["name"], "regression", len(values),
                                        len(base[key][1]), mean, mean_base,
                                        p_value=0.0))
            continue
        w_new, w_base = w_new[np.isfinite(w_new)], w_base[np.isfinite(w_base)]
        band, _ = tolerances.band_for(meta["name"])
        theta = shift_fraction * band.width(float(np.mean(np.abs(base[key][1]))))
        shift = float(w_new.mean() - w_base.mean())
        p = welch_shift_p(w_new, w_base, theta)
        p_better = welch_shift_p(-w_new, -w_base, theta)
        status = ("regression" if p < corrected else
                  "improved" if p_better < corrected else "ok")
        result.rows.append(ShiftRow(key, meta["name"], status, w_new.size, w_base.size, mean,
                                    mean_base, shift, theta, p))
    if result.regressions and not allow_regressions:
        result.verdict = "fail"
    return result


def _mean(values: list[float]) -> float | None:
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else None


def render_campaign_text(result: CampaignGateResult, record: dict[str, Any]) -> str:
    """The gate's verdict and its table, for a terminal or a CI log."""
    s = record["summary"]
    lines = [f"campaign gate: {result.verdict.upper()} ({record['dut'].get('name')}; campaign "
             f"{s['verdict']}: {s['reason']})"]
    lines += [f"  note: {n}" for n in result.notes]
    if result.rows:
        tested = sum(1 for r in result.rows if r.p_value is not None) or 1
        lines.append(f"  mean shift tested against its band, one-sided Welch, alpha "
                     f"{result.alpha:g} / {tested}")
    for r in result.rows:
        if r.status == "ok":
            continue
        detail = (f"mean {r.mean:.4g} vs {r.mean_base:.4g}, worse by {r.shift:.4g} "
                  f"(band {r.threshold:.4g}), p = {r.p_value:.2g}"
                  if r.shift is not None and r.mean is not None and r.mean_base is not None
                  and r.threshold is not None and r.p_value is not None else "")
        lines.append(f"  {r.status.upper():<12} {r.key} {detail}")
    ok = sum(1 for r in result.rows if r.status == "ok")
    if result.rows:
        lines.append(f"  {ok} of {len(result.rows)} measurements within their band")
    return "\n".join(lines)
