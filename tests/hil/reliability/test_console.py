"""The qualification console: measurement lines and the one-screen summary (#19)."""

from __future__ import annotations

from hil.console import SUMMARY_ROWS, measurement_line, summary_lines


def _m(name: str, value: float | None, outcome: str, **kw) -> dict:
    return {"name": name, "value": value, "unit": kw.pop("unit", "%"), "outcome": outcome,
            "low": kw.pop("low", None), "high": kw.pop("high", None),
            "conditions": kw.pop("conditions", {}), "marginal": kw.pop("marginal", False),
            "note": kw.pop("note", ""), "test": "t"}


def test_a_measurement_reads_as_one_line_with_its_limit() -> None:
    line = measurement_line(_m("flow.step.overshoot", 4.5123, "pass", high=5.0,
                               conditions={"target": 23}))
    assert line == "flow.step.overshoot[target=23] = 4.512 % PASS (limit <= 5)"
    assert measurement_line(_m("flow.bench.accuracy", 97.6, "pass", low=97.5,
                               marginal=True)).endswith("PASS (marginal) (limit >= 97.5)")
    assert measurement_line(_m("x", 1.2, "info", unit="s")) == "x = 1.2 s INFO"
    dead = measurement_line(_m("flow.bench.accuracy", None, "error", low=97.5,
                               note="the DUT stopped at t = 2.0 s (exited with SIGSEGV)"))
    assert dead.startswith("flow.bench.accuracy = nan % ERROR (limit >= 97.5) - the DUT "
                           "stopped at t = 2.0 s")


def test_the_summary_fits_a_screen_and_adds_up() -> None:
    ms = [_m(f"m{i}", 1.0, "fail", high=0.5) for i in range(40)]
    ms += [_m("ok", 0.1, "pass", high=0.5), _m("edge", 0.49, "pass", high=0.5, marginal=True)]
    lines = summary_lines(ms, [{"nodeid": "a::b", "outcome": "skipped"}], not_run=["a::c"])
    assert lines[0] == "measurements: 42 = 1 pass + 1 marginal + 40 fail"
    assert len(lines) <= SUMMARY_ROWS + 6
    assert any("and 25 more" in line for line in lines)
    assert lines[-1] == "not run (interrupted): 1 test"
