"""The run cache of a qualification session (hil.qualification.runs), without running a rig."""

from __future__ import annotations

from pathlib import Path

from hil.qualification.runs import RunCache, RunEntry, run_dir, slug, stopped_reason
from hil.rig import RunResult


def _result(tmp_path: Path, **record: object) -> RunResult:
    return RunResult(record={"verdict": "no-measurements", "error": None, **record},
                     out_dir=tmp_path, wall_s=0.5, sim_s=23.0)


def test_a_run_is_named_by_its_test_and_label() -> None:
    assert run_dir("fertilizer/test_flow_step.py::test_flow_step[23]") == \
        "runs/test_flow_step-23"
    assert run_dir("a.py::test_x", "baseline run") == "runs/test_x-baseline-run"
    assert slug("t::a/b c") == "a-b-c"


def test_a_cached_run_is_shared_and_each_test_that_used_it_is_known(tmp_path: Path) -> None:
    cache = RunCache()
    first = _result(tmp_path)
    assert cache.get(("k",), "t1") is None
    cache.add(("k",), RunEntry(first, "runs/t1", "bench-step-23"))
    cache.used("t1", first)
    assert cache.get(("k",), "t2") is first
    assert cache.of_test == {"t1": [first], "t2": [first]}
    assert cache.dir_of(first) == "runs/t1"
    assert cache.dir_of(_result(tmp_path)) == ""      # not this cache's run


def test_a_test_whose_dut_stopped_is_told_why(tmp_path: Path) -> None:
    cache = RunCache()
    good = _result(tmp_path)
    dead = _result(tmp_path, error="DutStopped", dut_stopped={"t_s": 3.04, "what": "SIGSEGV"})
    cache.add(("a",), RunEntry(good, "runs/a", "s"))
    cache.add(("b",), RunEntry(dead, "runs/b", "s"))
    cache.used("t", good)
    assert cache.dead_dut_reason("t") is None
    cache.used("t", dead)
    assert cache.dead_dut_reason("t") == "the DUT stopped at t = 3.0 s (SIGSEGV)"
    assert cache.first_dead("t") is dead
    assert stopped_reason(_result(tmp_path, error="bus lost")) == \
        "the run ended early: bus lost"


def test_the_record_rows_and_the_worst_timing(tmp_path: Path) -> None:
    cache = RunCache()
    calm = _result(tmp_path, timing={"mode": "realtime", "lateness_p99_s": 0.001})
    late = _result(tmp_path, timing={"mode": "realtime", "lateness_p99_s": 0.004})
    cache.add(("a",), RunEntry(calm, "runs/a", "s1"))
    cache.add(("b",), RunEntry(late, "runs/b", "s2"))
    rows, worst = cache.rows()
    assert worst is late.record["timing"]
    assert rows[0] == {"dir": "runs/a", "scenario": "s1", "verdict": "no-measurements",
                       "error": None, "sim_s": 23.0, "wall_s": 0.5}
    assert RunCache().rows() == ([], None)
