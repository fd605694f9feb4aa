"""Dispersion files: parsing, errors naming file and key, reproducible draws."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.campaign.dispersion import Distribution, load_dispersion
from hil.campaign.overrides import format_override, parse_overrides
from hil.cli.main import main
from hil.errors import ConfigError

ROOT = Path(__file__).resolve().parents[3]


#: a truncated normal whose mean is far outside its bounds: scipy refused it at the first draw
#: ("Domain error in arguments"), after the campaign had started
OUT_OF_RANGE = ('[meter.row_spread_sd_frac]\ndist = "truncnormal"\nmean = 1e308\nsd = 0.01\n'
                'low = 0.0\nhigh = 0.1\nsource = "x"\n')


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "disp.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("rig", ["fertilizer", "sowing_depth"])
def test_shipped_files_load_and_every_entry_has_a_source(rig: str) -> None:
    d = load_dispersion(ROOT / "plant_emulators" / rig / "dispersion.toml", rig=rig)
    assert len(d.parameters) >= 4
    assert all(len(dist.source) > 20 for dist in d.parameters.values())
    # every draw is a valid rig config
    for seed in range(5):
        items = [format_override(k, v) for k, v in d.draw(seed).items()]
        parse_overrides(items, rig=rig)


def test_draws_depend_on_the_seed_alone() -> None:
    d = load_dispersion(ROOT / "plant_emulators/fertilizer/dispersion.toml", rig="fertilizer")
    assert d.draw(7) == d.draw(7)
    assert d.draw(7) != d.draw(8)


def test_distributions_stay_in_their_support() -> None:
    rng = np.random.default_rng(1)
    t = Distribution("truncnormal", {"mean": 0.0, "sd": 1.0, "low": -0.5, "high": 0.2})
    u = Distribution("uniform", {"low": 2.0, "high": 3.0})
    n = Distribution("normal", {"mean": 5.0, "sd": 0.1})
    tv = [t.draw(rng) for _ in range(500)]
    assert min(tv) >= -0.5 and max(tv) <= 0.2
    assert all(2.0 <= u.draw(rng) <= 3.0 for _ in range(100))
    assert abs(np.mean([n.draw(rng) for _ in range(2000)]) - 5.0) < 0.01


@pytest.mark.parametrize(("text", "key", "words"), [
    ('[meter.no_such_thing]\ndist = "normal"\nmean = 1.0\nsd = 0.1\nsource = "x"\n',
     "meter.no_such_thing", "unknown parameter"),
    ('[meter.rows]\ndist = "normal"\nmean = 4.0\nsd = 0.1\nsource = "x"\n',
     "meter.rows", "not a real-valued"),
    ('[meter.row_spread_sd_frac]\ndist = "lognormal"\nmean = 1.0\nsd = 0.1\nsource = "x"\n',
     "meter.row_spread_sd_frac", "unknown distribution"),
    ('[meter.row_spread_sd_frac]\ndist = "normal"\nmean = 1.0\nsource = "x"\n',
     "meter.row_spread_sd_frac", "missing sd"),
    ('[meter.row_spread_sd_frac]\ndist = "uniform"\nlow = 1.0\nhigh = 0.5\nsource = "x"\n',
     "meter.row_spread_sd_frac", "must be below"),
    ('[meter.row_spread_sd_frac]\ndist = "normal"\nmean = 1.0\nsd = -1.0\nsource = "x"\n',
     "meter.row_spread_sd_frac", "sd must be > 0"),
    ('[meter.row_spread_sd_frac]\ndist = "normal"\nmean = 1.0\nsd = 1.0\n',
     "meter.row_spread_sd_frac.source", "needs a source"),
    ('[meter.row_spread_sd_frac]\ndist = "normal"\nmean = 1.0\nsd = 1.0\nscale = 2\n'
     'source = "x"\n', "meter.row_spread_sd_frac", "unknown scale"),
    # finite numbers out of range: each names the number, not numpy's or scipy's words
    (OUT_OF_RANGE, "meter.row_spread_sd_frac.mean", "mean is out of range"),
    ('[meter.row_spread_sd_frac]\ndist = "truncnormal"\nmean = 0.05\nsd = 1e-300\n'
     'low = 0.0\nhigh = 0.1\nsource = "x"\n', "meter.row_spread_sd_frac.sd",
     "within 1e+06 sd"),
    ('[meter.row_spread_sd_frac]\ndist = "uniform"\nlow = -1e308\nhigh = 1e308\n'
     'source = "x"\n', "meter.row_spread_sd_frac.high", "high - low overflows"),
    ('[meter.row_spread_sd_frac]\ndist = "normal"\nmean = 0.1\nsd = 1e307\n'
     'source = "x"\n', "meter.row_spread_sd_frac.sd", "overflows a float"),
    ('[meter.row_spread_sd_frac]\ndist = "normal"\nmean = 1.7e308\nsd = 1e306\n'
     'source = "x"\n', "meter.row_spread_sd_frac.mean", "overflows a float"),
])
def test_bad_entries_are_errors_naming_file_and_key(tmp_path: Path, text: str, key: str,
                                                    words: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        load_dispersion(path, rig="fertilizer")
    assert err.value.key == key
    assert str(path) in str(err.value) and words in str(err.value)


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found"):
        load_dispersion(tmp_path / "nope.toml", rig="fertilizer")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_dispersion(_write(tmp_path, "[a\n"), rig="fertilizer")


def test_overrides_round_trip_floats_exactly() -> None:
    value = 0.1 + 0.2  # 0.30000000000000004: repr keeps every bit
    table = parse_overrides([format_override("meter.row_spread_sd_frac", value)],
                            rig="fertilizer")
    assert table == {"meter": {"row_spread_sd_frac": value}}
    with pytest.raises(ConfigError, match="unknown key"):
        parse_overrides(["meter.nope=1.0"], rig="fertilizer")
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        parse_overrides(["meter.rows"], rig="fertilizer")


def test_a_number_out_of_range_is_exit_2_naming_file_table_and_key(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _write(tmp_path, OUT_OF_RANGE)
    code = main(["campaign", str(ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"),
                 "--samples", "1", "--bus", "inline", "--no-progress", "--dispersion",
                 str(path), "--out", str(tmp_path / "c")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1, err
    assert str(path) in err and "[meter.row_spread_sd_frac.mean]" in err, err
    assert "Domain error" not in err and "Traceback" not in err
    assert not (tmp_path / "c" / "samples").exists()
