"""TraceSet keeps rows in one flat buffer; the saved columns are those appended, bit for bit."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hil.record import TraceSet, load_traces
from hil.record.traces import write_npz


def test_columns_are_the_appended_values_bit_for_bit(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    traces = TraceSet()
    for name in ("a", "b", "c"):
        traces.declare(name, "1")
    rows = []
    for i in range(1000):
        row = (float(rng.standard_normal()), int(rng.integers(-5, 5)), math.nan if i % 7 else
               -0.0)
        rows.append((i * 0.01, row))
        traces.append(i * 0.01, row if i % 2 else list(row))
    assert len(traces) == 1000
    arrays, units = load_traces(traces.save_npz(tmp_path / "t.npz"))
    assert units == {"time_s": "s", "a": "1", "b": "1", "c": "1"}
    expected = np.array([[t, *r] for t, r in rows], dtype=np.float64)
    for j, name in enumerate(("time_s", "a", "b", "c")):
        assert arrays[name].view(np.uint64).tolist() == expected[:, j].view(np.uint64).tolist()


def test_a_bad_row_leaves_no_half_row_behind() -> None:
    traces = TraceSet()
    traces.declare("a", "1")
    traces.declare("b", "1")
    traces.append(0.0, (1.0, 2.0))
    with pytest.raises(TypeError):
        traces.append(0.01, (3.0, "x"))
    traces.append(0.02, (5.0, 6.0))
    arrays = traces.arrays()
    assert arrays["time_s"].tolist() == [0.0, 0.02] and arrays["b"].tolist() == [2.0, 6.0]


def test_no_rows_and_no_channels() -> None:
    traces = TraceSet()
    assert traces.arrays()["time_s"].size == 0
    traces.append(1.0, [])
    assert traces.arrays() == {"time_s": pytest.approx(np.array([1.0]))}


def test_write_npz_loads_as_numpys_own_savez(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    arrays = {"__units__": np.array('{"a": "V"}'), "a": rng.standard_normal(5000),
              "cells": rng.integers(0, 9, (300, 4)), "empty": np.zeros(0)}
    write_npz(tmp_path / "mine.npz", arrays)
    np.savez_compressed(tmp_path / "numpy.npz", **arrays)
    with np.load(tmp_path / "mine.npz") as mine, np.load(tmp_path / "numpy.npz") as theirs:
        assert mine.files == theirs.files
        for name in theirs.files:
            assert mine[name].dtype == theirs[name].dtype
            np.testing.assert_array_equal(mine[name], theirs[name])
