"""What a DUT is judged against: the catalogue's defaults, and how its profile departs from them.

Every measurement of the catalogue (:mod:`hil.limits`) that can judge has a default limit from
its standard; a profile's ``[limits]`` entry may *tighten* it freely, but an entry that
*loosens* it (a lower ``low``, a higher ``high``, a bound dropped, under any condition it
names) must say why in ``reason``. The default of a bus conformance check may be a rule of the
run (``<= the consuming node's heartbeat consumer time``) that no number can be compared
with: a profile's limit there replaces the rule and needs a reason too.

>>> from hil.condition_limits import ConditionCase
>>> class Entry:   # what a profile's [limits] entry offers (hil.dut.profile.Limit)
...     def __init__(self, low=None, high=None, reason=""):
...         self.low, self.high, self.cases, self.reason = low, high, (), reason
>>> loosening("flow.step.overshoot", Entry(high=4.0))
[]
>>> loosening("flow.step.overshoot", Entry(high=7.0))
['high 7 above the default 5']
>>> origin_of("flow.step.overshoot", Entry(high=4.0))
'tightened'
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from hil.condition_limits import ConditionCase
from hil.limits import MEASUREMENTS, MeasurementSpec, limit_text, measurement_names


class StatedLimit(Protocol):
    """A profile's ``[limits]`` entry as this module reads it (:class:`hil.dut.profile.Limit`)."""

    low: float | None
    high: float | None
    cases: tuple[ConditionCase, ...]
    reason: str


#: a default rule that starts with numbers: ">= -10, <= 10 (% of ...)", "<= 0, per message"
_RULE = re.compile(r"^(?:>= (?P<low>-?\d+(?:\.\d+)?))?(?:, )?(?:<= (?P<high>-?\d+(?:\.\d+)?))?"
                   r"(?=$|[ ,;(])")


def rule_band(rule: str) -> tuple[float | None, float | None] | None:
    """The numeric band a default rule starts with, or None where it is no number.

    >>> rule_band(">= -10, <= 10 (% of the declared cycle), per message")
    (-10.0, 10.0)
    >>> rule_band("<= the consuming rig node's heartbeat consumer time") is None
    True
    """
    match = _RULE.match(rule)
    if not match or not (match.group("low") or match.group("high")):
        return None
    low, high = match.group("low"), match.group("high")
    return (float(low) if low else None, float(high) if high else None)


def _default_bands(spec: MeasurementSpec, conditions: Mapping[str, tuple[Any, ...]]
                   ) -> list[tuple[float | None, float | None]] | None:
    """The catalogue's bands that may apply where ``conditions`` hold (a case of the
    catalogue that does not contradict them, and its own band); None for a rule no number
    states."""
    if spec.default_rule:
        band = rule_band(spec.default_rule)
        return None if band is None else [band]
    bands = [(spec.low, spec.high)]
    for case in spec.cases:
        if all(_may_meet(name, values, conditions) for name, values in case.conditions):
            bands.append((case.low, case.high))
    return bands


def _may_meet(name: str, values: tuple[Any, ...],
              conditions: Mapping[str, tuple[Any, ...]]) -> bool:
    """Whether a catalogue case's condition ``name`` (any of ``values``) can hold where a
    profile's case states ``conditions`` (it does not name it, or shares a value)."""
    if name not in conditions:
        return True
    one = ConditionCase(((name, values),), high=0.0)
    return any(one.matches({name: v}) for v in conditions[name])


def _looser(low: float | None, high: float | None, d_low: float | None,
            d_high: float | None) -> list[str]:
    out = []
    if d_low is not None and (low is None or low < d_low):
        out.append(f"low {'none' if low is None else f'{low:g}'} below the default {d_low:g}")
    if d_high is not None and (high is None or high > d_high):
        out.append(f"high {'none' if high is None else f'{high:g}'} above the default "
                   f"{d_high:g}")
    return out


def loosening(name: str, stated: StatedLimit) -> list[str]:
    """How the profile's entry for ``name`` loosens the catalogue's default (empty: it does
    not), each as words: ``high 7 above the default 5``, prefixed by the case's conditions
    for a ``when`` case."""
    spec = MEASUREMENTS[name]
    if spec.information:
        return []
    out: list[str] = []
    stated_bands: list[tuple[str, float | None, float | None, dict[str, tuple[Any, ...]]]] = []
    if stated.low is not None or stated.high is not None:
        stated_bands.append(("", stated.low, stated.high, {}))
    for case in stated.cases:
        stated_bands.append((f"{case.label}: ", case.low, case.high, dict(case.conditions)))
    for label, low, high, conditions in stated_bands:
        defaults = _default_bands(spec, conditions)
        if defaults is None:
            out.append(f"{label}replaces the default rule ({spec.default_rule})")
            continue
        for d_low, d_high in defaults:
            out.extend(label + words for words in _looser(low, high, d_low, d_high)
                       if label + words not in out)
    return out


def origin_of(name: str, stated: StatedLimit | None) -> str:
    """``default``, ``tightened``, ``loosened``, ``set`` (the catalogue has none) or
    ``information`` (neither has one)."""
    spec = MEASUREMENTS[name]
    has_default = (spec.low is not None or spec.high is not None or bool(spec.cases)
                   or bool(spec.default_rule))
    if stated is None:
        return "default" if has_default else "information"
    if not has_default:
        return "set"
    if loosening(name, stated):
        return "loosened"
    same = (not stated.cases and not spec.cases and not spec.default_rule
            and (stated.low, stated.high) == (spec.low, spec.high))
    return "default" if same else "tightened"


@dataclass(frozen=True)
class EffectiveLimit:
    """One measurement's limit for a DUT, and where it comes from.

    ``origin``: :func:`origin_of`. ``source``: the standard of the catalogue's default.
    ``text``: the limit in words. ``default_text``: the catalogue's. ``reason``: the profile's
    ``reason`` (a loosened limit always has one). ``information``: why the measurement is
    information only, where it is.
    """

    name: str
    unit: str
    origin: str
    text: str
    default_text: str
    source: str
    reason: str = ""
    information: str = ""

    def describe(self) -> str:
        """Where the limit comes from, in words (``hil profile check`` prints it)."""
        if self.origin == "information":
            return f"information only: {self.information}"
        if self.origin == "default":
            return f"default from {self.source or '(no source stated in the catalogue)'}"
        if self.origin == "set":
            return "set by the profile (the catalogue judges it not: " \
                   f"{self.information or 'no default'})"
        why = f"; reason: {self.reason}" if self.reason else ""
        return (f"{self.origin} (default {self.default_text}, from "
                f"{self.source or '(no source stated)'}){why}")

    def to_dict(self) -> dict[str, str]:
        return {"name": self.name, "unit": self.unit, "limit": self.text,
                "origin": self.origin, "default": self.default_text, "source": self.source,
                "reason": self.reason, "information": self.information}


def _text(low: float | None, high: float | None, cases: tuple[ConditionCase, ...],
          default: str) -> str:
    return limit_text(low, high, cases, otherwise=f"the default ({default})")


def effective_limits(rig: str, stated: Mapping[str, StatedLimit]) -> list[EffectiveLimit]:
    """Every measurement of ``rig``'s catalogue with the limit a DUT whose profile states
    ``stated`` (its ``[limits]``) is judged against."""
    out = []
    for name in measurement_names(rig):
        spec = MEASUREMENTS[name]
        entry = stated.get(name)
        default = _default_text(spec)
        text = default if entry is None else _text(entry.low, entry.high, entry.cases, default)
        out.append(EffectiveLimit(name=name, unit=spec.unit, origin=origin_of(name, entry),
                                  text=text, default_text=default, source=spec.source,
                                  reason=entry.reason if entry is not None else "",
                                  information=spec.information))
    return out


def _default_text(spec: MeasurementSpec) -> str:
    if spec.default_rule:
        return spec.default_rule
    return limit_text(spec.low, spec.high, spec.cases, otherwise="none")


def counts(limits: list[EffectiveLimit]) -> tuple[int, int]:
    """How many of ``limits`` judge, and how many are information only."""
    info = sum(1 for lim in limits if lim.origin == "information")
    return len(limits) - info, info




@dataclass(frozen=True)
class RecordedLimit:
    """A profile's ``[limits]`` entry as a qualification record keeps it (its ``limits``
    table), read back for :func:`loosening` and :func:`origin_of`."""

    low: float | None
    high: float | None
    cases: tuple[ConditionCase, ...]
    reason: str

    @classmethod
    def parse(cls, entry: Mapping[str, Any]) -> RecordedLimit:
        """From ``{"low", "high", "when": [{"conditions", "low", "high"}, ...], "reason"}``
        (what :func:`record_limits` writes; ``when`` and ``reason`` may be absent)."""
        cases = []
        for case in entry.get("when") or []:
            table = {**(case.get("conditions") or {}),
                     **{k: case[k] for k in ("low", "high", "marginal")
                        if case.get(k) is not None}}
            cases.append(ConditionCase.parse(table))
        return cls(_number(entry.get("low")), _number(entry.get("high")), tuple(cases),
                   str(entry.get("reason") or ""))


def _number(value: Any) -> float | None:
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) \
        else None


def record_limits(stated: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """A profile's ``[limits]`` (:class:`hil.dut.profile.Limit` by name) as the record's
    ``limits`` table: each entry's band, unit, cases (``when``), and where it stands against
    the catalogue: ``origin`` (:func:`origin_of`), the ``default`` it departs from with its
    ``source``, and the profile's ``reason`` (always there for a loosened limit)."""
    out: dict[str, dict[str, Any]] = {}
    for name, lim in stated.items():
        spec = MEASUREMENTS[name]
        entry: dict[str, Any] = {"low": lim.low, "high": lim.high, "unit": spec.unit}
        if lim.cases:
            entry["when"] = [case.to_dict() for case in lim.cases]
        entry.update(origin=origin_of(name, lim), default=_default_text(spec),
                     source=spec.source or spec.information)
        if getattr(lim, "reason", ""):
            entry["reason"] = lim.reason
        out[name] = entry
    return out
