"""Measurements: a named value with units, limits and an outcome (after OpenHTF).

Where the limits come from (a DUT profile's entry, one of its per-condition cases, the
catalogue) is the measurement's ``limit_source``.

>>> m = Measurement("flow.step.overshoot", 3.1, "%", high=5.0, conditions={"target_gps": 23})
>>> m.outcome, m.marginal
(<Outcome.PASS: 'pass'>, False)
>>> Measurement("flow.step.overshoot", 4.95, "%", high=5.0).marginal
True
>>> Measurement("flow.bench.accuracy", 98.6, "%", low=97.5).marginal
False
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any


class Outcome(StrEnum):
    PASS = "pass"
    FAIL = "fail"
    #: the value could not be computed (the DUT produced no usable signal, say)
    ERROR = "error"
    #: recorded for information only (no limits)
    INFO = "info"


@dataclass(frozen=True)
class Measurement:
    """One checked quantity. ``marginal`` is set when a passing value lies closer to a limit
    than ``marginal_band`` (in the value's unit) when given, else than ``marginal_fraction``
    of the limit span (two-sided limits) or ``one_sided_fraction`` of the limit's magnitude
    (one-sided: 5 % of a 97.5 % accuracy limit would be 4.9 points, calling nearly every
    pass marginal)."""

    name: str
    value: float
    unit: str
    low: float | None = None
    high: float | None = None
    conditions: dict[str, Any] = field(default_factory=dict)
    marginal_fraction: float = 0.05
    note: str = ""
    one_sided_fraction: float = 0.01
    marginal_band: float | None = None
    #: which limit applied: ``profile``, ``profile (to_mm=20)`` (a per-condition case),
    #: ``catalogue``, ``catalogue (...)``, ``none`` (:func:`hil.limits.applied_limit`); empty
    #: where the code that judged it does not say (the bus conformance checks)
    limit_source: str = ""

    @property
    def outcome(self) -> Outcome:
        if self.value is None or (isinstance(self.value, float) and math.isnan(self.value)):
            return Outcome.ERROR
        if self.low is None and self.high is None:
            return Outcome.INFO
        if self.low is not None and self.value < self.low:
            return Outcome.FAIL
        if self.high is not None and self.value > self.high:
            return Outcome.FAIL
        return Outcome.PASS

    @property
    def marginal(self) -> bool:
        if self.outcome is not Outcome.PASS:
            return False
        if self.marginal_band is not None:
            band = self.marginal_band
        elif self.low is not None and self.high is not None:
            band = self.marginal_fraction * (self.high - self.low)
        else:
            limit = self.low if self.low is not None else self.high
            band = self.one_sided_fraction * abs(limit or 0.0)
        return bool((self.low is not None and self.value - self.low < band)
                    or (self.high is not None and self.high - self.value < band))

    def to_dict(self) -> dict[str, Any]:
        value = None if isinstance(self.value, float) and math.isnan(self.value) else self.value
        return {"name": self.name, "value": value, "unit": self.unit, "low": self.low,
                "high": self.high, "conditions": self.conditions, "outcome": self.outcome.value,
                "marginal": self.marginal, "note": self.note, "limit_source": self.limit_source}
