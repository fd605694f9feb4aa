"""Tolerance files: bands, precedence of exact names and globs, and the errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.errors import ConfigError
from hil.gate import DEFAULT_TOLERANCES, Band, load_tolerances

ROOT = Path(__file__).resolve().parents[3]


def _toml(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "tol.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_band_width_is_the_wider_of_abs_and_rel() -> None:
    band = Band(abs=0.2, rel=0.1)
    assert band.width(1.0) == 0.2          # 0.1 * 1.0 = 0.1 < 0.2
    assert band.width(-5.0) == 0.5         # magnitude of the baseline
    assert Band(rel=0.05).width(0.0) == 0.0
    assert DEFAULT_TOLERANCES.band_for("flow.step.overshoot") == (Band(rel=0.05), "default")


def test_exact_name_beats_globs_and_the_most_specific_glob_wins(tmp_path) -> None:
    tol = load_tolerances(_toml(tmp_path, """
[default]
abs = 9.0
[measurements]
"flow.*" = { abs = 1.0 }
"flow.step.*" = { abs = 2.0 }
"flow.step.response_time" = { abs = 3.0 }
"flow.step.overshoo?" = { abs = 4.0 }
"""))
    assert tol.band_for("flow.step.response_time") == (Band(abs=3.0), "flow.step.response_time")
    assert tol.band_for("flow.step.overshoot") == (Band(abs=4.0), "flow.step.overshoo?")
    assert tol.band_for("flow.step.steady_state_error") == (Band(abs=2.0), "flow.step.*")
    assert tol.band_for("flow.bench.accuracy") == (Band(abs=1.0), "flow.*")
    assert tol.band_for("depth.field.cv") == (Band(abs=9.0), "default")


def test_equally_specific_globs_go_by_file_order(tmp_path) -> None:
    tol = load_tolerances(_toml(tmp_path, """
[measurements]
"flow.step.*" = { abs = 1.0 }
"*.step.overshoot" = { abs = 2.0 }
"""))
    # "flow.step." and ".step.overshoot" are 10 and 15 literal characters: the latter wins
    assert tol.band_for("flow.step.overshoot")[0] == Band(abs=2.0)
    # "depth.fi*" and "*field.cv" both have 8 literal characters: the first in the file wins
    tie = load_tolerances(_toml(tmp_path, """
[measurements]
"depth.fi*" = { abs = 1.0 }
"*field.cv" = { abs = 2.0 }
"""))
    assert tie.band_for("depth.field.cv") == (Band(abs=1.0), "depth.fi*")
    swapped = load_tolerances(_toml(tmp_path, """
[measurements]
"*field.cv" = { abs = 2.0 }
"depth.fi*" = { abs = 1.0 }
"""))
    assert swapped.band_for("depth.field.cv") == (Band(abs=2.0), "*field.cv")
    # without a [default] table the built-in default applies
    assert tie.band_for("flow.bench.accuracy") == (Band(rel=0.05), "default")


@pytest.mark.parametrize(("text", "key", "message"), [
    ('[measurements]\n"flow.step.overshoot" = { abss = 1.0 }',
     '[measurements."flow.step.overshoot".abss]', "unknown key (expected one of: abs, rel)"),
    ('[measurements]\n"flow.step.*" = { abs = -0.1 }', '[measurements."flow.step.*"]',
     "abs must be a finite number >= 0, got -0.1"),
    ("[default]\nrel = -1", "[default]", "rel must be a finite number >= 0"),
    ('[measurements]\n"flow.step.overshoot" = {}', '[measurements."flow.step.overshoot"]',
     "a band needs abs and/or rel"),
    ('[measurements]\n"flow.step.overshoot" = 1.0', '[measurements."flow.step.overshoot"]',
     "expected a table like { abs = 0.1 }"),
    ('[measurements]\n"flow.step.overshot" = { abs = 1.0 }',
     '[measurements."flow.step.overshot"]', "unknown measurement name"),
    ('[measurements]\n"flw.*" = { abs = 1.0 }', '[measurements."flw.*"]',
     "pattern matches no known measurement name"),
    ('[measurements]\n"flow.step.overshoot" = { abs = "1" }',
     '[measurements."flow.step.overshoot".abs]', "expected a number"),
    ("[defaults]\nrel = 0.1", "[defaults]", "unknown key (expected one of: default, measurements)"),
])
def test_a_bad_tolerance_file_names_file_and_key(tmp_path, text, key, message) -> None:
    path = _toml(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_tolerances(path)
    assert str(info.value).startswith(f"{path}: {key} ") and message in str(info.value)


def test_unreadable_tolerance_files_name_the_file(tmp_path) -> None:
    with pytest.raises(ConfigError, match=r"tol\.toml: not valid TOML"):
        load_tolerances(_toml(tmp_path, "[default\n"))
    with pytest.raises(ConfigError, match=r"none\.toml: tolerance file not found"):
        load_tolerances(tmp_path / "none.toml")


def test_the_projects_tolerance_file_loads_with_the_documented_bands() -> None:
    tol = load_tolerances(ROOT / "ci" / "tolerances.toml")
    assert tol.default == Band(rel=0.05)
    assert tol.band_for("flow.step.response_time")[0] == Band(abs=0.2)
    assert tol.band_for("flow.field.accuracy")[0] == Band(abs=1.0)
    assert tol.band_for("depth.step.overshoot") == (Band(abs=1.0), "depth.step.*")
    assert tol.band_for("depth.step.response_time") == (Band(abs=0.2),
                                                        "depth.step.response_time")
    assert tol.band_for("depth.step.steady_state_error") == (Band(abs=1.0), "depth.step.*")
    assert tol.band_for("depth.step.true_steady_state_error") == (
        Band(abs=0.8), "depth.step.true_steady_state_error")
    assert tol.band_for("depth.field.mean")[0] == Band(abs=0.5)
    assert tol.band_for("flow.restart.recovery_time") == (Band(abs=0.2),
                                                          "flow.restart.recovery_time")
    assert tol.band_for("depth.busload.pass_rate")[0] == Band(abs=2.5)
    assert tol.band_for("flow.busload.accuracy") == (Band(rel=0.05), "default")
