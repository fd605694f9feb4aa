"""The qualification's summary counts its measurements by whether a limit judged them
(issue 43: "the qualification's summary says how many measurements were judged and how many
were information only")."""

from __future__ import annotations

import math

from hil.qualification.summary import judged, summary, summary_line


def _m(low: float | None, high: float | None, outcome: str) -> dict[str, object]:
    return {"name": "x", "value": 1.0, "low": low, "high": high, "outcome": outcome}


def test_a_measurement_with_either_bound_is_judged_one_with_neither_is_information() -> None:
    ms = [_m(None, 5.0, "pass"), _m(97.5, None, "fail"), _m(1.0, 2.0, "pass"),
          _m(None, None, "info"), _m(None, None, "info")]
    assert [judged(m) for m in ms] == [True, True, True, False, False]
    assert summary(ms) == {"measurements": 5, "judged": 3, "information_only": 2}


def test_judged_is_about_the_limit_not_the_outcome() -> None:
    """A value that could not be computed (NaN, outcome ``error``) still had a limit, or not:
    it counts where its limit puts it, and the totals add up."""
    nan = math.nan
    ms = [{**_m(None, 5.0, "error"), "value": nan}, {**_m(None, None, "error"), "value": nan}]
    counts = summary(ms)
    assert counts == {"measurements": 2, "judged": 1, "information_only": 1}
    assert counts["judged"] + counts["information_only"] == counts["measurements"]


def test_the_console_line_says_both_numbers() -> None:
    assert summary_line(summary([_m(None, 5.0, "pass"), _m(None, None, "info")])) == (
        "judged: 1 of 2 measurements had a limit; 1 information only (no limit)")
    assert summary(()) == {"measurements": 0, "judged": 0, "information_only": 0}
