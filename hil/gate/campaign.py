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

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import t as student_t

from hil.gate.campaign_baseline import (
    Moments,
    SideStats,
    is_compact,
    stats_from_compact,
    stats_from_samples,
    worseness,
)
from hil.gate.campaign_requirement import RequirementVerdict, judge_requirement, worse
from hil.gate.completeness import interrupted_samples
from hil.gate.tolerance import DEFAULT_TOLERANCES, Tolerances

__all__ = ["CampaignGateResult", "ShiftRow", "compare_campaigns", "render_campaign_text",
           "welch_moments_p", "welch_shift_p", "worseness"]

ALPHA = 0.01
SHIFT_FRACTION = 0.25
#: the campaign gate's exit status by verdict (anything else, no verdict: 2)
EXIT_CODES = {"pass": 0, "fail": 1, "inconclusive": 3}


@dataclass(frozen=True)
class ShiftRow:
    """One measurement's comparison."""

    key: str
    name: str
    #: ok | regression | improved | missing | no-direction | limits-changed (a two-sided
    #: limit moved since a compact baseline) | no-value (never computed on one side)
    status: str
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
    verdict: str            # pass | fail | inconclusive | error
    campaign_verdict: str
    rows: list[ShiftRow] = field(default_factory=list)
    alpha: float = ALPHA
    notes: list[str] = field(default_factory=list)
    requirement: RequirementVerdict | None = None

    @property
    def exit_code(self) -> int:
        """0 pass, 1 fail, 3 inconclusive, 2 no verdict."""
        return EXIT_CODES.get(self.verdict, 2)

    @property
    def regressions(self) -> list[ShiftRow]:
        return [r for r in self.rows if r.status in ("regression", "missing")]


def welch_shift_p(new: np.ndarray, base: np.ndarray, threshold: float) -> float:
    """One-sided p-value of ``mean(new) - mean(base) > threshold`` (Welch's t-test)."""
    a, b = Moments.of(new), Moments.of(base)
    if a is None or b is None:
        raise ValueError("Welch's test needs a finite value on each side")
    return welch_moments_p(a, b, threshold)


def welch_moments_p(new: Moments, base: Moments, threshold: float) -> float:
    """:func:`welch_shift_p` from each side's count, mean and variance (all the test needs,
    and all a compact baseline keeps)."""
    n1, n2 = new.n, base.n
    # numpy floats: an absurd value (a hand-edited baseline) overflows to inf, not an error
    d = np.float64(new.mean) - np.float64(base.mean)
    v1 = np.float64(new.var) / n1 if n1 > 1 else np.float64(0.0)
    v2 = np.float64(base.var) / n2 if n2 > 1 else np.float64(0.0)
    se2 = v1 + v2
    if se2 == 0.0:
        return 0.0 if d > threshold else 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        df = se2 * se2 / ((v1 * v1 / (n1 - 1) if n1 > 1 else 0.0)
                          + (v2 * v2 / (n2 - 1) if n2 > 1 else 0.0))
        return float(student_t.sf((d - threshold) / np.sqrt(se2), df))


def _baseline_stats(baseline: dict[str, Any]) -> dict[str, SideStats]:
    return stats_from_compact(baseline) if is_compact(baseline) else stats_from_samples(baseline)


def compare_campaigns(record: dict[str, Any], baseline: dict[str, Any] | None,
                      tolerances: Tolerances = DEFAULT_TOLERANCES, *, alpha: float = ALPHA,
                      shift_fraction: float = SHIFT_FRACTION,
                      allow_regressions: bool = False) -> CampaignGateResult:
    """Gate a campaign: its verdict on its requirement (the worse of the record's own and the
    one recomputed from its samples, :mod:`hil.gate.campaign_requirement`), then (with a
    baseline: another campaign record or a compact baseline) the shift of every mean."""
    recorded = record["summary"]["verdict"]
    path = str(record.get("_path", "campaign.json"))
    judged = judge_requirement(record, path=path)
    own = worse(recorded, judged.verdict or "error")
    result = CampaignGateResult(verdict="pass", campaign_verdict=own, alpha=alpha,
                                requirement=judged)
    cut = interrupted_samples(record)
    if cut:
        shown = ", ".join(str(i) for i in cut[:10]) + (" …" if len(cut) > 10 else "")
        result.notes.append(
            f"the campaign was interrupted in part: {len(cut)} of "
            f"{record['samples_requested']} samples were interrupted ({shown}; a worker "
            f"stopped under them) and did not run; the verdict is the one the samples that "
            f"ran settle whatever those would have given")
    if own == "error":
        result.verdict = "error"
        result.notes.append("the campaign has no verdict (no sample completed, or its "
                            "stopping rule had not decided)")
        return result
    if own != recorded:
        result.notes.append(f"the record says {recorded}, its samples say {judged.verdict}: "
                            f"{judged.reason}")
    if own in ("fail", "inconclusive"):
        result.verdict = own
        result.notes.append(f"the campaign itself is {own}: {record['summary']['reason']}")
    if record.get("status") != "complete":
        result.notes.append(f"the campaign is {record.get('status')}: "
                            f"{len(record['samples'])} of {record['samples_requested']} samples")
    if baseline is None:
        return result
    if baseline["dut"].get("name") != record["dut"].get("name"):
        result.notes.append(f"baseline of {baseline['dut'].get('name')}, record of "
                            f"{record['dut'].get('name')}")
    result.notes += source_notes(record, baseline)
    new, base = stats_from_samples(record), _baseline_stats(baseline)
    compared = [k for k in base if k in new]
    corrected = alpha / max(1, len(compared))
    for key in sorted(set(base) | set(new)):
        if key not in new:
            result.rows.append(ShiftRow(key, base[key].name, "missing", n_base=base[key].n))
            continue
        if key not in base:
            continue
        a, b = new[key], base[key]
        row = {"key": key, "name": a.name, "n": a.n, "n_base": b.n, "mean": a.mean,
               "mean_base": b.mean}
        w_new, w_base = a.worse(a.low, a.high), b.worse(a.low, a.high)
        if w_new is None or w_base is None:
            result.rows.append(ShiftRow(status="no-direction", **row))
            continue
        if a.not_computed and not b.not_computed:
            result.rows.append(ShiftRow(status="regression", p_value=0.0, **row))
            continue
        if isinstance(w_new, str) or isinstance(w_base, str):
            result.rows.append(ShiftRow(status="limits-changed" if "changed" in (w_new, w_base)
                                        else "no-value", **row))
            continue
        band, _ = tolerances.band_for(a.name)
        theta = shift_fraction * band.width(b.mean_abs or 0.0)
        p = welch_moments_p(w_new, w_base, theta)
        p_better = welch_moments_p(w_new.negated(), w_base.negated(), theta)
        status = ("regression" if p < corrected else
                  "improved" if p_better < corrected else "ok")
        result.rows.append(ShiftRow(status=status, shift=w_new.mean - w_base.mean,
                                    threshold=theta, p_value=p, **row))
    if result.regressions and not allow_regressions:
        result.verdict = "fail"
    return result


def source_notes(record: dict[str, Any], baseline: dict[str, Any]) -> list[str]:
    """What differs between how the record's and the baseline's samples were drawn (suites,
    -k, bus, clock, dispersion): a shift may then be the difference of the campaigns."""
    src = baseline.get("source") if is_compact(baseline) else baseline
    if not isinstance(src, dict):
        return []
    notes = []
    for key in ("suites", "keyword", "bus", "clock"):
        if src.get(key) != record.get(key):
            notes.append(f"the baseline's {key} is {src.get(key)!r}, the record's "
                         f"{record.get(key)!r}")

    def sha(d: Any) -> Any:
        return d.get("sha256") if isinstance(d, dict) else None
    if sha(src.get("dispersion")) != sha(record.get("dispersion")):
        notes.append("the baseline was drawn from another dispersion file")
    return notes


def render_campaign_text(result: CampaignGateResult, record: dict[str, Any]) -> str:
    """The gate's verdict and its table, for a terminal or a CI log."""
    s = record["summary"]
    lines = [f"campaign gate: {result.verdict.upper()} ({record['dut'].get('name')}; campaign "
             f"{s['verdict']}: {s['reason']})"]
    req, stated = result.requirement, record.get("requirement")
    if req is not None:
        need = (f"pass probability {stated['pass_probability']:g} at "
                f"{stated['confidence']:.0%} confidence" if stated else
                "no requirement stated: every sample must pass")
        used = (f"; decided after {req.samples_run} of {req.samples_requested} samples "
                f"({req.rule})" if req.samples_run < req.samples_requested else "")
        lines.append(f"  requirement: {need}: {(req.verdict or 'undecided').upper()}"
                     f"{used}")
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
