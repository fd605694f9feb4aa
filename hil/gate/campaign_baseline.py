"""Compact campaign baselines: what the campaign gate's shift test needs of a campaign, in a
few kB instead of the 1.5 MB of a 300-sample ``campaign.json``.

Schema ``agrihil.campaign-baseline/1``, written by ``hil gate CAMPAIGN.json --baseline
PATH --update-baseline`` (:func:`compact_baseline`)::

    {"schema": "agrihil.campaign-baseline/1",
     "dut": {...identity...}, "rig": "fertilizer",
     "n": 300,                                   # judged samples the statistics are of
     "source": {"campaign_id", "started_at", "seed", "samples_requested", "samples_run",
                "bus", "clock", "suites", "keyword", "dispersion": {"path", "sha256"}},
     "requirement": {...} | null, "summary": {"judged", "passed", "failed", "errors",
                                              "verdict"},
     "measurements": {"flow.step.overshoot[sensor=sliding,target_gps=23]": {
         "name", "conditions", "unit", "low", "high",
         "n", "not_computed", "passed",           # samples, of them not computed, passing
         "mean", "sd", "min", "max", "mean_abs",  # of the computed values
         "quantiles": {"0.05": ..., "0.25": ..., "0.5": ..., "0.75": ..., "0.95": ...},
         "worse": {"n", "mean", "sd"}}}}          # of "how bad" under low/high (the test's)

The shift test (:mod:`hil.gate.campaign`) is Welch's t-test on "how bad": it needs the count,
mean and SD of that quantity, which ``worse`` keeps (under the limits of the baseline; a
one-sided limit's "how bad" is the value or its negative, so it is also derived from the
value's mean and SD when a limit moved).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.campaign.record import clean
from hil.gate.jsonfile import Fields
from hil.gate.keys import measurement_key

SCHEMA = "agrihil.campaign-baseline/1"
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


@dataclass(frozen=True)
class Moments:
    """Count, mean and variance (ddof 1; 0 for a single value) of finite values."""

    n: int
    mean: float
    var: float

    @classmethod
    def of(cls, values: np.ndarray) -> Moments | None:
        x = np.asarray(values, dtype=float)
        x = x[np.isfinite(x)]
        if not x.size:
            return None
        return cls(int(x.size), float(x.mean()), float(x.var(ddof=1)) if x.size > 1 else 0.0)

    def negated(self) -> Moments:
        return Moments(self.n, -self.mean, self.var)


def worseness(values: Any, low: float | None, high: float | None) -> np.ndarray | None:
    """Values as "how bad" (larger is worse), or None when the limits give no direction."""
    x = np.asarray(values, dtype=float)
    if low is not None and high is not None:
        return np.abs(x - 0.5 * (low + high))
    if high is not None:
        return x
    if low is not None:
        return -x
    return None


@dataclass(frozen=True)
class SideStats:
    """One measurement of one side of the comparison, as the shift test sees it."""

    name: str
    low: float | None
    high: float | None
    n: int
    not_computed: int
    mean: float | None          # of the computed values
    mean_abs: float | None
    #: "how bad" under (low, high) given as arguments: None when they give no direction,
    #: "changed" when a compact baseline cannot say it under other limits
    values: np.ndarray | None = None
    value_moments: Moments | None = None
    worse_moments: Moments | None = None

    def worse(self, low: float | None, high: float | None) -> Moments | str | None:
        if self.values is not None:
            w = worseness(self.values, low, high)
            return None if w is None else (Moments.of(w) or "empty")
        if low is None and high is None:
            return None
        if (low, high) == (self.low, self.high) and self.worse_moments is not None:
            return self.worse_moments
        if self.value_moments is not None and (low is None or high is None):
            return self.value_moments if low is None else self.value_moments.negated()
        return "changed" if self.value_moments is not None else "empty"


def stats_from_samples(doc: Mapping[str, Any]) -> dict[str, SideStats]:
    """Per measurement key, the judged samples' values of a campaign record."""
    raw: dict[str, tuple[Mapping[str, Any], list[float], int]] = {}
    for s in doc["samples"]:
        if s["verdict"] not in ("pass", "fail"):
            continue
        for m in s["measurements"]:
            key = measurement_key(m["name"], m.get("conditions") or {})
            value = m.get("value")
            meta, values, passed = raw.setdefault(key, (m, [], 0))
            values.append(math.nan if value is None else float(value))
            ok = m.get("outcome") not in ("fail", "error")
            raw[key] = (meta, values, passed + int(ok))
    out = {}
    for key, (meta, values, _) in raw.items():
        x = np.asarray(values, dtype=float)
        finite = x[np.isfinite(x)]
        out[key] = SideStats(
            name=meta["name"], low=meta.get("low"), high=meta.get("high"), n=x.size,
            not_computed=int(x.size - finite.size),
            mean=float(finite.mean()) if finite.size else None,
            mean_abs=float(np.abs(finite).mean()) if finite.size else None,
            values=x, value_moments=Moments.of(x))
    return out


def compact_baseline(doc: Mapping[str, Any], *, created_at: str) -> dict[str, Any]:
    """The compact baseline of a (complete) campaign record."""
    measurements: dict[str, Any] = {}
    passed_by_key: dict[str, int] = {}
    for s in doc["samples"]:
        if s["verdict"] not in ("pass", "fail"):
            continue
        for m in s["measurements"]:
            key = measurement_key(m["name"], m.get("conditions") or {})
            passed_by_key[key] = passed_by_key.get(key, 0) + int(
                m.get("outcome") not in ("fail", "error"))
    conditions = {measurement_key(m["name"], m.get("conditions") or {}): m
                  for s in doc["samples"] for m in s["measurements"]}
    for key, st in sorted(stats_from_samples(doc).items()):
        assert st.values is not None
        finite = st.values[np.isfinite(st.values)]
        vm = st.value_moments
        w = worseness(st.values, st.low, st.high)
        wm = Moments.of(w) if w is not None else None
        measurements[key] = {
            "name": st.name, "conditions": conditions[key].get("conditions") or {},
            "unit": conditions[key].get("unit"), "low": st.low, "high": st.high,
            "n": st.n, "not_computed": st.not_computed, "passed": passed_by_key.get(key, 0),
            "mean": st.mean, "sd": math.sqrt(vm.var) if vm else None,
            "min": float(finite.min()) if finite.size else None,
            "max": float(finite.max()) if finite.size else None,
            "mean_abs": st.mean_abs,
            "quantiles": ({f"{q:g}": float(np.quantile(finite, q)) for q in QUANTILES}
                          if finite.size else {}),
            "worse": ({"n": wm.n, "mean": wm.mean, "sd": math.sqrt(wm.var)} if wm else None)}
    summary = doc["summary"]
    dispersion = doc.get("dispersion")
    rig = doc.get("rig")
    return clean({      # an overflowed moment (inf) is no number: null
        "schema": SCHEMA,
        "dut": {k: _relative(v) if k == "profile" else v for k, v in doc["dut"].items()
                if k != "parameters"},
        "rig": rig.get("name") if isinstance(rig, Mapping) else rig,
        "n": summary["judged"],
        "created_at": created_at,
        "source": {"campaign_id": doc.get("campaign_id"), "started_at": doc.get("started_at"),
                   "seed": doc.get("seed"), "samples_requested": doc["samples_requested"],
                   "samples_run": len(doc["samples"]), "bus": doc.get("bus"),
                   "clock": doc.get("clock"), "suites": doc.get("suites"),
                   "keyword": doc.get("keyword"),
                   "dispersion": ({"path": _relative(dispersion.get("path")),
                                   "sha256": dispersion.get("sha256")}
                                  if isinstance(dispersion, Mapping) else None)},
        "requirement": doc.get("requirement"),
        "summary": {k: summary[k] for k in ("judged", "passed", "failed", "errors", "verdict")},
        "measurements": measurements,
    })


def _relative(path: Any) -> Any:
    """A path inside the project as relative to it (a stored baseline names no machine)."""
    from pathlib import Path

    from hil.dut.build import PROJECT_ROOT

    if not isinstance(path, str):
        return path
    try:
        return str(Path(path).resolve().relative_to(PROJECT_ROOT.resolve()))
    except ValueError:
        return path


def is_compact(doc: Any) -> bool:
    return isinstance(doc, Mapping) and doc.get("schema") == SCHEMA


def load_compact(doc: Any, *, path: str) -> dict[str, Any]:
    """Check a compact baseline read from ``path`` (every field the gate reads, typed);
    :class:`ConfigError` naming the file and the key otherwise."""
    top = Fields(doc, path=path)
    if not top.child("dut").string("name"):
        raise top.error("dut.name", "must not be empty")
    top.string("rig")
    n = top.data.get("n")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise top.error("n", f"expected an integer >= 1, got {n!r}")
    top.child("source").mapping("dispersion", required=False)
    for key, item in top.mapping("measurements").items():
        m = Fields(item, path=path, prefix=f"measurements.{key}")
        name = m.string("name")
        if measurement_key(name, m.mapping("conditions")) != key:
            raise m.error("name", f"the key is not the identity of {name!r} and its "
                                  f"conditions")
        for field in ("low", "high", "mean", "sd", "mean_abs"):
            m.number(field)
        if (m.number("sd") or 0.0) < 0:
            raise m.error("sd", f"a standard deviation is >= 0, got {m.data['sd']!r}")
        for field in ("n", "not_computed", "passed"):
            count = m.data.get(field)
            if isinstance(count, bool) or not isinstance(count, int) or count < 0:
                raise m.error(field, f"expected an integer >= 0, got {count!r}")
        if m.data["not_computed"] > m.data["n"] or m.data["passed"] > m.data["n"]:
            raise m.error("n", f"{m.data['n']} samples, fewer than not_computed "
                               f"{m.data['not_computed']} or passed {m.data['passed']}")
        if m.data.get("worse") is not None:
            w = m.child("worse")
            w.number("mean", nullable=False)
            if (w.number("sd", nullable=False) or 0.0) < 0:
                raise w.error("sd", f"a standard deviation is >= 0, got {w.data['sd']!r}")
            if not isinstance(w.data.get("n"), int) or w.data["n"] < 1:
                raise w.error("n", f"expected an integer >= 1, got {w.data.get('n')!r}")
    return dict(doc) | {"_path": path}


def stats_from_compact(doc: Mapping[str, Any]) -> dict[str, SideStats]:
    out = {}
    for key, m in doc["measurements"].items():
        computed = m["n"] - m["not_computed"]
        sd = m["sd"] or 0.0
        vm = (Moments(computed, m["mean"], sd * sd)
              if computed and m["mean"] is not None else None)
        w = m.get("worse")
        wm = Moments(w["n"], w["mean"], w["sd"] * w["sd"]) if w else None
        out[key] = SideStats(name=m["name"], low=m["low"], high=m["high"], n=m["n"],
                             not_computed=m["not_computed"], mean=m["mean"],
                             mean_abs=m["mean_abs"], value_moments=vm, worse_moments=wm)
    return out

