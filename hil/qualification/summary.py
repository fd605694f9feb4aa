"""How much of a qualification judged anything: its measurements counted by whether a limit
applied to them.

A measurement is *judged* when a limit applied to it (a low or a high bound, from the
profile's ``[limits]`` or the catalogue's default): it can pass or fail. It is *information
only* when none did: it is recorded (outcome ``info``) and can never fail the DUT, whatever
its value. A qualification that passes while judging little says little; the record's
``summary`` and the console's end summary say how much it judged.

>>> summary([{"low": None, "high": 5.0}, {"low": None, "high": None}])
{'measurements': 2, 'judged': 1, 'information_only': 1}
>>> summary_line(summary([{"low": 1.0, "high": None}]))
'judged: 1 of 1 measurement had a limit; 0 information only (no limit)'
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any


def judged(m: dict[str, Any]) -> bool:
    """Whether a limit applied to the record's measurement ``m`` (a low or a high bound)."""
    return m.get("low") is not None or m.get("high") is not None


def summary(measurements: Iterable[dict[str, Any]]) -> dict[str, int]:
    """The record's ``summary``: how many measurements, how many judged, how many not."""
    ms = list(measurements)
    n_judged = sum(1 for m in ms if judged(m))
    return {"measurements": len(ms), "judged": n_judged, "information_only": len(ms) - n_judged}


def summary_line(counts: dict[str, int]) -> str:
    """The console's line for a :func:`summary`."""
    n = counts["measurements"]
    return (f"judged: {counts['judged']} of {n} measurement{'s' if n != 1 else ''} had a limit; "
            f"{counts['information_only']} information only (no limit)")
