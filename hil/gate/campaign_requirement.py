"""The campaign gate's verdict on the stated requirement, recomputed from the samples.

The gate does not take a campaign's word for its verdict: it counts the judged samples of the
record, reads the requirement the record carries (the profile's ``[campaign]``) and its
stopping rule (``decision.rule``), and applies the same functions the campaign stopped by
(:mod:`hil.campaign.decision`, :mod:`hil.campaign.stats`):

* all N samples in: the exact (Clopper-Pearson) verdict, **pass** when the one-sided lower
  bound at ``confidence`` reaches ``pass_probability``, **fail** when the upper bound stays
  below it, **inconclusive** otherwise; without a requirement, pass when no sample failed;
* fewer (a campaign that stopped early): the verdict only when the rule settles it from these
  samples (curtailment: whatever the missing samples would give; SPRT: a boundary crossed by
  the samples in index order); otherwise the record is incomplete and has no verdict.

So an early-stopped record is complete by its rule, checked here, and an interrupted or
truncated one never is (:func:`campaign_incomplete_reason`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from hil.campaign.decision import JUDGED, RULES, decide
from hil.campaign.stats import verdict as exact_verdict
from hil.errors import ConfigError
from hil.gate.completeness import incomplete_reason
from hil.gate.jsonfile import Fields

#: worse last: the gate keeps the worse of the record's own verdict and its own
ORDER = ("pass", "inconclusive", "fail")
_SEQUENTIAL_KEYS = ("sequential_good_probability", "sequential_alpha")


@dataclass(frozen=True)
class RequirementVerdict:
    """The requirement's verdict (None: not settled by these samples), why, and the counts."""

    verdict: str | None
    reason: str
    rule: str
    samples_run: int
    samples_requested: int


def requirement_of(doc: Mapping[str, Any], *, path: str) -> dict[str, float] | None:
    """The record's ``requirement`` (None: none stated), each number checked against the
    profile key's range; :class:`ConfigError` naming the file and the key otherwise."""
    if doc.get("requirement") is None:
        return None
    from hil.validation import PROFILE_RANGES, check_value

    req = Fields(doc["requirement"], path=path, prefix="requirement")
    out: dict[str, float] = {}
    for name in ("pass_probability", "confidence", *_SEQUENTIAL_KEYS):
        value = req.number(name, required=name in ("pass_probability", "confidence"),
                           nullable=False)
        if value is None:
            continue
        try:
            check_value(value, PROFILE_RANGES[f"campaign.{name}"], what=name)
        except ValueError as exc:
            raise req.error(name, str(exc)) from exc
        out[name] = value
    return out


def rule_of(doc: Mapping[str, Any], requirement: dict[str, float] | None, *, path: str) -> str:
    """The record's stopping rule (records from before early decisions: ``fixed``)."""
    if doc.get("decision") is None:
        return "fixed"
    rule = Fields(doc["decision"], path=path, prefix="decision").string("rule")
    if rule not in RULES:
        raise ConfigError(f"{rule!r} is not one of {list(RULES)}", path=path,
                          key="decision.rule")
    if rule == "sequential":
        missing = [k for k in _SEQUENTIAL_KEYS if requirement is None or k not in requirement]
        if missing:
            raise ConfigError("a sequential campaign must state its test", path=path,
                              key=f"requirement.{missing[0]}")
    return rule


def judge_requirement(doc: Mapping[str, Any], *, path: str) -> RequirementVerdict:
    """The verdict of the record's samples on its requirement (see the module)."""
    requirement = requirement_of(doc, path=path)
    rule = rule_of(doc, requirement, path=path)
    # an interrupted sample did not run (a worker stopped under it): missing, not judged
    samples = [{"index": s["index"], "verdict": s["verdict"]} for s in doc["samples"]
               if s["verdict"] != "interrupted"]
    total = int(doc["samples_requested"])
    judged = [s for s in samples if s["verdict"] in JUDGED]
    passed = sum(1 for s in judged if s["verdict"] == "pass")
    errors = len(samples) - len(judged)
    counts = {"rule": rule, "samples_run": len(samples), "samples_requested": total}
    if rule == "sequential":
        d = decide(rule, samples, total, requirement)
        return RequirementVerdict(d.verdict, d.reason, **counts)
    if len(samples) >= total:
        p = requirement["pass_probability"] if requirement else None
        c = requirement["confidence"] if requirement else 0.95
        v = exact_verdict(passed, len(judged), pass_probability=p, confidence=c,
                          errors=errors)
        return RequirementVerdict(v.verdict, v.reason, **counts)
    if requirement is None:
        return RequirementVerdict(None, "no requirement: every sample must be run", **counts)
    d = decide("curtailed", samples, total, requirement)
    return RequirementVerdict(d.verdict, d.reason, **counts)


def worse(a: str, b: str) -> str:
    """The worse of two campaign verdicts (``error`` worst of all: no verdict)."""
    if "error" in (a, b):
        return "error"
    return max(a, b, key=ORDER.index)


def campaign_incomplete_reason(doc: Any, *, path: str) -> str | None:
    """:func:`hil.gate.completeness.incomplete_reason`, except that a complete campaign that
    stopped early is complete when its stopping rule settles the verdict from its samples."""
    reason = incomplete_reason(doc, path=path)
    if reason is None or not isinstance(doc, Mapping) or doc.get("status") != "complete":
        return reason
    try:
        settled = judge_requirement(doc, path=path).verdict
    except (ConfigError, KeyError, TypeError, ValueError, AttributeError):
        return reason       # a damaged record: the loader says what is wrong with it
    if settled is not None:
        return None
    return reason + " (its stopping rule had not decided)"
