"""The gate's one rule for every record kind: an interrupted or incomplete record is never a
pass.

A qualification record (``agrihil.qualification/1``) and a campaign record
(``agrihil.campaign/1``) both say whether they finished (a campaign that says ``complete`` may
still hold samples whose own run was interrupted, a worker stopped under them: those samples did
not run, and count as missing); the gate asks this module before it
judges anything, with or without a baseline, and a record that did not finish gets no verdict
(``hil gate`` exits 2 saying why). A qualification that failed before it was cut short has
already failed and is judged as a fail.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["incomplete_reason", "interrupted_samples"]


def _count(value: Any) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _qualification(doc: Mapping[str, Any], path: str) -> str | None:
    verdict = doc.get("verdict")
    complete = doc.get("complete", True) is not False
    if verdict != "interrupted" and (complete or verdict == "fail"):
        return None      # complete, or cut short after failing already: judged as a fail
    done, planned = _count(doc.get("tests_completed")), _count(doc.get("tests_planned"))
    after = "" if planned is None else f" after {done or 0} of {planned} tests"
    return (f"{path}: the qualification was interrupted{after}; an incomplete record has no "
            f"verdict: run hil qualify again")


def interrupted_samples(doc: Mapping[str, Any]) -> list[int]:
    """The indices of the samples of a campaign record that were interrupted (their own
    qualification cut short: a worker stopped under them), which the campaign did not run."""
    samples = doc.get("samples")
    if not isinstance(samples, list):
        return []
    return [s.get("index") for s in samples
            if isinstance(s, Mapping) and s.get("verdict") == "interrupted"]


def _indices(indices: list[int]) -> str:
    shown = ", ".join(str(i) for i in indices[:10])
    return shown + (f" and {len(indices) - 10} more" if len(indices) > 10 else "")


def _campaign(doc: Mapping[str, Any], path: str) -> str | None:
    status = doc.get("status")
    samples = doc.get("samples")
    cut = interrupted_samples(doc)
    # an interrupted sample did not run: it counts as missing, not as a sample
    finished = (len(samples) if isinstance(samples, list) else 0) - len(cut)
    requested = _count(doc.get("samples_requested"))
    if status == "complete" and (requested is None or finished >= requested):
        return None
    what = status if status in ("interrupted", "running") else "incomplete"
    if status == "complete":
        what = ("interrupted in part" if cut else "incomplete although it says complete")
    partly = (f"; {len(cut)} interrupted: {_indices(cut)}" if cut else "")
    return (f"{path}: the campaign is {what} ({finished} of "
            f"{requested if requested is not None else '?'} samples run{partly}); an "
            f"incomplete campaign has no verdict: run hil campaign again")


def incomplete_reason(doc: Any, *, path: str) -> str | None:
    """Why the gate must not judge ``doc`` (None: it may).

    Parameters
    ----------
    doc : Any
        The record as read from JSON: a qualification or a campaign record (anything else is
        left to the record's own loader to refuse).
    path : str
        The file, named in the reason.

    Returns
    -------
    str or None
        One line naming the file and why it has no verdict, or None when it finished.

    Examples
    --------
    >>> why = incomplete_reason({"schema": "agrihil.campaign/1", "status": "interrupted",
    ...                          "samples": [], "samples_requested": 4}, path="c.json")
    >>> why.split(";")[0]
    'c.json: the campaign is interrupted (0 of 4 samples run)'
    """
    if not isinstance(doc, Mapping):
        return None
    schema = doc.get("schema")
    if schema == "agrihil.campaign/1":
        return _campaign(doc, path)
    if schema == "agrihil.qualification/1":
        return _qualification(doc, path)
    return None
