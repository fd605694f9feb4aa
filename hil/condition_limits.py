"""Limits stated per condition: a band that applies only where a measurement's conditions match.

A measurement's limit may depend on the conditions it was measured under (the step's target,
the run's speed, the map's zone): a profile's ``[limits]`` entry and a catalogue entry
(:mod:`hil.limits`) may each carry cases, tried in order; the first whose conditions all match
gives the limit, else the entry's own band applies.

>>> case = ConditionCase.parse({"to_mm": 20, "high": 2.0})
>>> case.label, case.matches({"from_mm": 30.0, "to_mm": 20.0})
('to_mm=20', True)
>>> ConditionCase.parse({"zone": ["A", "B"], "low": 97.0}).matches({"zone": "C"})
False
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from hil.errors import ConfigError

#: what a condition's value may be, by kind; a case's value must be of the condition's kind
KINDS = ("number", "text", "bool")
#: the keys of a case that state its band; every other key is a condition
BAND_KEYS = ("low", "high", "marginal")

ConditionValue = bool | int | float | str


def kind_of(value: Any) -> str | None:
    """``number``, ``text`` or ``bool`` for a condition's value; None for anything else."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int | float):
        return "number" if math.isfinite(value) else None
    if isinstance(value, str):
        return "text"
    return None


def _same(a: ConditionValue, b: ConditionValue) -> bool:
    if kind_of(a) != kind_of(b):
        return False
    if kind_of(a) == "number":
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
    return a == b


def _text(value: ConditionValue) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer():
        return f"{value:g}"
    return str(value)


def check_band(low: float | None, high: float | None, marginal: float | None) -> None:
    """Raise ``ValueError`` for ``low`` above ``high`` or a negative ``marginal``."""
    if low is not None and high is not None and low > high:
        raise ValueError(f"low {low} is above high {high}")
    if marginal is not None and marginal < 0:
        raise ValueError(f"marginal must be >= 0, got {marginal}")


@dataclass(frozen=True)
class ConditionCase:
    """A band that applies to a measurement whose conditions match all of ``conditions``.

    Parameters
    ----------
    conditions : tuple of (str, tuple of values)
        Each condition's name and the values it matches (any of them); not empty.
    low, high : float, optional
        The band, in the measurement's unit; at least one. Nothing is taken from the entry's
        own band: a case states its limit whole.
    marginal : float, optional
        The marginal band of :class:`hil.measurements.Measurement` (default: its own rule).
    """

    conditions: tuple[tuple[str, tuple[ConditionValue, ...]], ...]
    low: float | None = None
    high: float | None = None
    marginal: float | None = None

    def __post_init__(self) -> None:
        if not self.conditions:
            raise ValueError("a case needs at least one condition besides low, high, marginal")
        if self.low is None and self.high is None:
            raise ValueError("a case needs low, high or both")
        check_band(self.low, self.high, self.marginal)

    @classmethod
    def parse(cls, table: Mapping[str, Any], key: str = "") -> ConditionCase:
        """A case from a TOML table: ``low``/``high``/``marginal`` and conditions.

        A condition's value is a number, a string or a boolean, or an array of them (any of
        them matches). Errors are :class:`ConfigError` naming ``key`` and the sub-key.
        """
        if not isinstance(table, Mapping):
            raise ConfigError(f"expected a table of conditions and low/high, got "
                              f"{type(table).__name__}", key=key or None)
        band: dict[str, float] = {}
        conditions: list[tuple[str, tuple[ConditionValue, ...]]] = []
        for name, value in table.items():
            where = f"{key}.{name}" if key else str(name)
            if name in BAND_KEYS:
                if kind_of(value) != "number":
                    raise ConfigError(f"expected a number, got {value!r}", key=where)
                band[name] = float(value)
                continue
            values = tuple(value) if isinstance(value, list | tuple) else (value,)
            if not values:
                raise ConfigError("expected a value or a non-empty array of values",
                                  key=where)
            kinds = {kind_of(v) for v in values}
            if None in kinds or len(kinds) != 1:
                raise ConfigError(f"a condition's value is a number, a string or a boolean "
                                  f"(or an array of one of them), got {value!r}", key=where)
            conditions.append((str(name), values))
        try:
            return cls(tuple(conditions), **band)
        except ValueError as exc:
            raise ConfigError(str(exc), key=key or None) from exc

    @property
    def names(self) -> tuple[str, ...]:
        """The conditions' names."""
        return tuple(name for name, _ in self.conditions)

    @property
    def label(self) -> str:
        """The conditions as ``name=value`` pairs (``|`` between alternatives)."""
        return ", ".join(f"{name}={'|'.join(_text(v) for v in values)}"
                         for name, values in self.conditions)

    def kind(self, name: str) -> str:
        """The kind of the values the case gives condition ``name``."""
        values = dict(self.conditions)[name]
        return kind_of(values[0]) or ""

    def matches(self, conditions: Mapping[str, Any]) -> bool:
        """Whether every condition of the case is among ``conditions`` with one of its values."""
        return all(name in conditions and any(_same(conditions[name], v) for v in values)
                   for name, values in self.conditions)

    def problem(self, conditions: Mapping[str, Any], *, strict: bool) -> str | None:
        """Why the case cannot be judged against ``conditions``, or None.

        A value of another kind than the measurement's (a string against a number) is always
        one; a condition the measurement does not carry is one when ``strict`` (the catalogue
        does not say which conditions the measurement may carry).
        """
        for name, _ in self.conditions:
            if name not in conditions:
                if strict:
                    have = ", ".join(sorted(conditions)) or "none"
                    return f"names condition {name!r}, which this measurement does not have " \
                           f"(it has: {have})"
                continue
            theirs, ours = kind_of(conditions[name]), self.kind(name)
            if theirs != ours:
                return f"gives condition {name!r} a {ours} where this measurement's is a " \
                       f"{theirs or type(conditions[name]).__name__} " \
                       f"({conditions[name]!r})"
        return None

    def to_dict(self) -> dict[str, Any]:
        """The case as a record keeps it: conditions (a value or a list) and the band."""
        return {"conditions": {name: values[0] if len(values) == 1 else list(values)
                               for name, values in self.conditions},
                "low": self.low, "high": self.high,
                **({"marginal": self.marginal} if self.marginal is not None else {})}


def when(conditions: Mapping[str, ConditionValue | Sequence[ConditionValue]], *,
         low: float | None = None, high: float | None = None,
         marginal: float | None = None) -> ConditionCase:
    """A case, as the catalogue (:mod:`hil.limits`) writes one: ``when({"to_mm": 20}, high=2)``."""
    table: dict[str, Any] = dict(conditions)
    table.update({k: v for k, v in (("low", low), ("high", high), ("marginal", marginal))
                  if v is not None})
    return ConditionCase.parse(table)


def select(cases: Sequence[ConditionCase], conditions: Mapping[str, Any], *,
           strict: bool) -> tuple[int | None, str | None]:
    """The index of the first case that matches ``conditions``, and the first problem.

    Every case is checked for problems (:meth:`ConditionCase.problem`), not only those before
    the match: a case that cannot be judged is a mistake in the limits wherever it stands.

    Returns
    -------
    tuple of (int or None, str or None)
        ``(index, None)`` for a match, ``(None, None)`` for none, ``(None, "when[i] ...")``
        for a problem.
    """
    for i, case in enumerate(cases):
        problem = case.problem(conditions, strict=strict)
        if problem:
            return None, f"when[{i}] {problem}"
    for i, case in enumerate(cases):
        if case.matches(conditions):
            return i, None
    return None, None


def check_names(cases: Sequence[ConditionCase], known: Mapping[str, str], *,
                what: str) -> tuple[str, str] | None:
    """The first case condition not in ``known`` (name -> kind), or of another kind.

    Returns
    -------
    tuple of (str, str) or None
        The sub-key (``when[i].name``) and the message, or None when all are known.
    """
    for i, case in enumerate(cases):
        for name in case.names:
            if name not in known:
                listed = ", ".join(sorted(known)) or "none"
                return (f"when[{i}].{name}",
                        f"{what} has no condition {name!r} (it has: {listed})")
            if case.kind(name) != known[name]:
                return (f"when[{i}].{name}",
                        f"condition {name!r} of {what} is a {known[name]}, got a "
                        f"{case.kind(name)}")
    return None
