"""What a qualification prints while it runs: each measurement as it is judged, and a
one-screen summary at the end (used by the pytest plugin, so ``hil qualify`` and a plain
``pytest --hil-dut`` print the same)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from hil.limits import is_conformance as conformance_name

#: the summary lists at most this many failed measurements (the record has them all)
SUMMARY_ROWS = 15


def limit_text(low: float | None, high: float | None) -> str:
    """A measurement's limits as a reader says them: ``<= 5``, ``>= 97.5``, ``in [a, b]``."""
    if low is not None and high is not None:
        return f"in [{low:g}, {high:g}]"
    if high is not None:
        return f"<= {high:g}"
    if low is not None:
        return f">= {low:g}"
    return "info, no limit"


def conditions_text(conditions: dict[str, Any]) -> str:
    """``[target_gps=23, row=2]`` (empty for no conditions)."""
    if not conditions:
        return ""
    return "[" + ", ".join(f"{k}={v}" for k, v in sorted(conditions.items())) + "]"


def measurement_line(m: dict[str, Any]) -> str:
    """One measurement of the record as one console line, e.g.
    ``flow.step.overshoot[target_gps=23] = 4.51 % PASS (limit <= 5)``."""
    value = m.get("value")
    shown = "nan" if value is None or (isinstance(value, float) and math.isnan(value)) \
        else f"{value:.4g}"
    outcome = str(m.get("outcome", "?")).upper()
    if m.get("marginal"):
        outcome += " (marginal)"
    limits = ("" if m.get("low") is None and m.get("high") is None
              else f" (limit {limit_text(m.get('low'), m.get('high'))})")
    line = (f"{m['name']}{conditions_text(m.get('conditions') or {})} = {shown} "
            f"{m.get('unit', '')} {outcome}{limits}")
    note = str(m.get("note") or "")
    if m.get("outcome") in ("fail", "error") and note:
        line += f" - {note[:160]}"
    return " ".join(line.split())


def is_conformance(m: dict[str, Any]) -> bool:
    """A bus conformance check (``bus.*``, ``isobus.claim.*`` ...:
    :func:`hil.limits.is_conformance`), recorded for every run of a qualification."""
    return conformance_name(str(m.get("name", "")))


def conformance_line(measurements: Iterable[dict[str, Any]]) -> str:
    """One line for a test's bus conformance checks, e.g.
    ``bus conformance: 13 checks over 1 run, all pass``."""
    ms = list(measurements)
    runs = {m.get("run") for m in ms}
    bad = sum(1 for m in ms if m.get("outcome") in ("fail", "error"))
    verdict = f"{bad} failed" if bad else "all pass"
    return (f"bus conformance: {len(ms)} check{'s' if len(ms) != 1 else ''} over {len(runs)} "
            f"run{'s' if len(runs) != 1 else ''}, {verdict}")


def test_lines(measurements: Iterable[dict[str, Any]], *,
               verbose: bool = False) -> list[tuple[str, bool]]:
    """What the console prints under a test: (line, is it a failure).

    The control measurements one per line; the bus conformance checks as one summary line, then
    each failed check on its own line; every check with ``verbose`` (or when any fails, the
    failing ones only: the record and the report have the others).
    """
    ms = list(measurements)
    bus = [m for m in ms if is_conformance(m)]
    out = [(measurement_line(m), m.get("outcome") in ("fail", "error"))
           for m in ms if not is_conformance(m)]
    if bus:
        bad = [m for m in bus if m.get("outcome") in ("fail", "error")]
        out.append((conformance_line(bus), bool(bad)))
        shown = bus if verbose else bad
        out += [("  " + measurement_line(m), m.get("outcome") in ("fail", "error"))
                for m in shown]
    return out


def summary_lines(measurements: Iterable[dict[str, Any]], tests: Iterable[dict[str, Any]],
                  *, not_run: Iterable[str] = ()) -> list[str]:
    """The end-of-qualification summary (counts, failed measurements, failed and unrun
    tests), short enough for one screen."""
    ms = list(measurements)
    counts: dict[str, int] = {}
    for m in ms:
        key = "marginal" if m.get("marginal") else str(m.get("outcome"))
        counts[key] = counts.get(key, 0) + 1
    order = ("pass", "marginal", "info", "fail", "error")
    out = [f"measurements: {len(ms)} = " + (" + ".join(
        f"{counts[k]} {k}" for k in order if counts.get(k)) or "none")]
    bad = [m for m in ms if m.get("outcome") in ("fail", "error")]
    if bad:
        out.append(f"failed ({len(bad)}):")
        out += [f"  {measurement_line(m)}" for m in bad[:SUMMARY_ROWS]]
        if len(bad) > SUMMARY_ROWS:
            out.append(f"  … and {len(bad) - SUMMARY_ROWS} more (see the record)")
    tests = list(tests)
    failed_tests = [t for t in tests if t.get("outcome") == "failed"
                    and not t.get("message", "").startswith("measurements out of limits")]
    if failed_tests:
        out.append(f"tests that failed without a failed measurement ({len(failed_tests)}):")
        out += [f"  {t['nodeid'].split('::', 1)[-1]}: "
                f"{' '.join(str(t.get('message', '')).split())[:150]}"
                for t in failed_tests[:SUMMARY_ROWS]]
    skipped = sum(1 for t in tests if t.get("outcome") == "skipped")
    if skipped:
        out.append(f"skipped: {skipped} test{'s' if skipped != 1 else ''} (reasons in the "
                   f"record)")
    unrun = list(not_run)
    if unrun:
        out.append(f"not run (interrupted): {len(unrun)} test{'s' if len(unrun) != 1 else ''}")
    return out
