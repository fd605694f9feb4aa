"""The gate's one rule for every record kind: an interrupted or incomplete record is never a
pass.

A qualification record (``agrihil.qualification/1``) and a campaign record
(``agrihil.campaign/1``) both say whether they finished; the gate asks this module before it
judges anything, with or without a baseline, and a record that did not finish gets no verdict
(``hil gate`` exits 2 saying why). A qualification that failed before it was cut short has
already failed and is judged as a fail.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["incomplete_reason"]


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


def _campaign(doc: Mapping[str, Any], path: str) -> str | None:
    status = doc.get("status")
    samples = doc.get("samples")
    finished = len(samples) if isinstance(samples, list) else 0
    requested = _count(doc.get("samples_requested"))
    if status == "complete" and (requested is None or finished >= requested):
        return None
    what = status if status in ("interrupted", "running") else "incomplete"
    if status == "complete":
        what = "incomplete although it says complete"
    return (f"{path}: the campaign is {what} ({finished} of "
            f"{requested if requested is not None else '?'} samples); an incomplete campaign "
            f"has no verdict: run hil campaign again")


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
    'c.json: the campaign is interrupted (0 of 4 samples)'
    """
    if not isinstance(doc, Mapping):
        return None
    schema = doc.get("schema")
    if schema == "agrihil.campaign/1":
        return _campaign(doc, path)
    if schema == "agrihil.qualification/1":
        return _qualification(doc, path)
    return None
