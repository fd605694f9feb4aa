"""The shared test vectors (contract section 3): every file replays through the Python cores
within 1e-9, and the committed files are what the generator writes today."""

from __future__ import annotations

from pathlib import Path

import pytest

from reference_controllers.vectors import (
    DEPTH_COLUMNS,
    FERTILIZER_COLUMNS,
    VECTOR_DIR,
    params_line,
    read_vector,
    replay,
    write_vector,
)
from reference_controllers.vectors.generate import all_vectors

FILES = sorted(VECTOR_DIR.glob("*.csv"))


def test_the_required_vectors_exist() -> None:
    names = {p.stem for p in FILES}
    assert {"fertilizer-physical", "fertilizer-paper-literal", "fertilizer-open-loop",
            "depth-fuzzy-pid"} <= names


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_vector_replays_within_tolerance(path: Path) -> None:
    vector = read_vector(path)
    assert vector.columns in (FERTILIZER_COLUMNS, DEPTH_COLUMNS)
    assert len(vector.rows) >= 300
    bad = replay(vector)
    assert not bad, f"{len(bad)} mismatches, first (row, column, expected, got): {bad[0]}"


def test_committed_vectors_are_up_to_date(tmp_path: Path) -> None:
    """A change of a core or of its defaults must come with regenerated vectors
    (``python -m reference_controllers.vectors``), or the C build checks stale numbers."""
    for name, vector in all_vectors().items():
        fresh = tmp_path / f"{name}.csv"
        write_vector(fresh, dict(vector.params), vector.columns, vector.rows)
        committed = VECTOR_DIR / f"{name}.csv"
        assert committed.exists(), f"{committed.name} missing: run the generator"
        assert committed.read_text() == fresh.read_text(), f"{committed.name} is stale"


def test_format_is_exact(tmp_path: Path) -> None:
    path = tmp_path / "x.csv"
    write_vector(path, {"mode": "physical", "kp1": 0.1}, ("a", "b"), [(0.1, 1.0 / 3.0)])
    lines = path.read_text().splitlines()
    assert lines[0] == "#params mode=physical kp1=0.1" == params_line({"mode": "physical",
                                                                        "kp1": 0.1})
    assert lines[2] == "0.10000000000000001,0.33333333333333331"
    assert read_vector(path).rows == [(0.1, 1.0 / 3.0)]


def test_a_wrong_output_is_caught(tmp_path: Path) -> None:
    vector = read_vector(VECTOR_DIR / "fertilizer-physical.csv")
    rows = list(vector.rows)
    q, p, has, new, volts, seg = rows[50]
    rows[50] = (q, p, has, new, volts + 2e-9, seg)
    bad = replay(type(vector)(vector.params, vector.columns, rows))
    assert [(r, c) for r, c, *_ in bad] == [(50, "volts")]
