"""The verdict of a qualification session, from what it recorded (a pure function).

``pass``: every selected test ran and passed, and every measurement is within its limits.
``fail``: a measurement out of its limits, a failed test, a DUT that stopped, or a session
stopped at its first failure (``pytest -x``). ``interrupted``: some selected tests did not run.
``invalid-bench``: a real-time run's timing was out of bounds (nothing said about the DUT).
``error``: a setup error, pytest's own error, or no measurement at all.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import pytest


def session_verdict(*, setup_error: str, complete: bool, interrupted: bool,
                    exitstatus: int | None, invalid_bench: Mapping[str, str],
                    dut_failures: Mapping[str, str], measurements: Iterable[dict[str, Any]],
                    tests: Iterable[dict[str, Any]]) -> str:
    """The verdict of a session.

    Parameters
    ----------
    setup_error : str
        A setup problem that ended the session ("" if none).
    complete : bool
        Whether every selected test ran and nobody interrupted the session.
    interrupted : bool
        Whether a SIGINT/SIGTERM ended it.
    exitstatus : int, optional
        pytest's exit status (None while the session runs).
    invalid_bench : mapping
        Tests whose real-time runs had invalid timing.
    dut_failures : mapping
        Tests failed because their DUT stopped.
    measurements, tests : iterable of dict
        The record's measurements and tests (``outcome`` keys).

    Returns
    -------
    str
        ``pass``, ``fail``, ``interrupted``, ``invalid-bench`` or ``error``.
    """
    ms, ts = list(measurements), list(tests)
    if setup_error:
        return "error"
    if not complete:
        stopped_on_failure = (not interrupted and exitstatus != pytest.ExitCode.INTERRUPTED
                              and any(t["outcome"] == "failed" for t in ts))
        # never a pass: some selected tests did not run (a session stopped at its first
        # failure, pytest -x, is a fail, though incomplete)
        return "fail" if stopped_on_failure else "interrupted"
    if invalid_bench:
        return "invalid-bench"
    if exitstatus in (pytest.ExitCode.INTERRUPTED, pytest.ExitCode.INTERNAL_ERROR,
                      pytest.ExitCode.USAGE_ERROR):
        return "error"
    if dut_failures:
        return "fail"     # a DUT that stopped fails, measured or not
    if not ms:
        return "error"
    if any(m["outcome"] in ("fail", "error") for m in ms):
        return "fail"
    if any(t["outcome"] == "failed" for t in ts):
        return "fail"
    return "pass"
