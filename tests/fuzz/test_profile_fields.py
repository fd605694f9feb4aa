"""Profile fields are used or refused (#22.8): ``wiring.database`` and
``timing.control_period_ms``, through the loader, ``hil profile check`` and ``hil run``."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.dut.profile import load_profile, rig_control_period_ms
from hil.errors import ConfigError
from tests.fuzz.cli import assert_refused, run_cli

ROOT = Path(__file__).resolve().parents[2]
DAEMON = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
DEPTH = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-daemon.toml"
DBC_LINE = 'database = "plant_emulators/fertilizer/db/fertilizer.dbc"'


def _copy(tmp_path: Path, source: Path, old: str, new: str) -> Path:
    text = source.read_text()
    assert old in text
    path = tmp_path / source.name
    path.write_text(text.replace(old, new))
    return path


@pytest.mark.parametrize(("database", "words"), [
    ("nowhere/fertilizer.dbc", "not found"),
    ("plant_emulators/fertilizer/db", "is not a file"),
    ("{corrupt}", "cannot be read"),
    ("{empty}", "declares no frames"),
])
def test_a_missing_or_corrupt_database_is_refused(database: str, words: str,
                                                  tmp_path: Path) -> None:
    if database == "{corrupt}":
        database = str(tmp_path / "corrupt.dbc")
        Path(database).write_bytes(b'VERSION ""\nBO_ 544 X: 8 Y\n SG_ broken\xff\n')
    elif database == "{empty}":
        database = str(tmp_path / "empty.dbc")
        Path(database).write_text('VERSION ""\n')
    path = _copy(tmp_path, DAEMON, DBC_LINE, f'database = "{database}"')
    with pytest.raises(ConfigError, match=words) as caught:
        load_profile(path)
    assert caught.value.key == "wiring.database" and str(path) in str(caught.value)
    assert_refused(run_cli("profile", "check", str(path)), path, database)
    outcome = run_cli("run", "--dut", str(path), "--scenario", "bench-step-23",
                      "--bus", "inline", "--out", str(tmp_path / "run"))
    assert_refused(outcome, path, database)
    assert "[wiring.database]" in outcome.stderr
    assert not (tmp_path / "run").exists()


def test_the_shipped_databases_are_read(tmp_path: Path) -> None:
    for profile in (DAEMON, DEPTH):
        assert load_profile(profile).wiring.database.endswith(".dbc")
    # a database beside the profile (relative to it) is found too
    (tmp_path / "db").mkdir()
    (tmp_path / "db" / "mine.dbc").write_bytes(
        (ROOT / "plant_emulators/fertilizer/db/fertilizer.dbc").read_bytes())
    load_profile(_copy(tmp_path, DAEMON, DBC_LINE, 'database = "db/mine.dbc"'))


@pytest.mark.parametrize("period", ["1e9", "50", "100.5", "0", "-100", "nan", "inf"])
def test_a_control_period_that_disagrees_with_the_rig_is_refused(period: str,
                                                                 tmp_path: Path) -> None:
    path = _copy(tmp_path, DAEMON, "control_period_ms = 100", f"control_period_ms = {period}")
    with pytest.raises(ConfigError) as caught:
        load_profile(path)
    assert caught.value.key is not None and caught.value.key.startswith("timing")
    assert_refused(run_cli("profile", "check", str(path)), path, period)
    assert_refused(run_cli("run", "--dut", str(path), "--scenario", "bench-step-23",
                           "--bus", "inline", "--out", str(tmp_path / "run")), path, period)


def test_the_control_period_follows_the_rigs_configured_sync_period(tmp_path: Path) -> None:
    assert rig_control_period_ms("fertilizer") == (100.0, False)
    assert rig_control_period_ms("sowing_depth") == (10.0, True)
    # the depth rig's SYNC period is configurable: a profile that sets both agrees
    text = DEPTH.read_text().replace("control_period_ms = 10\n", "control_period_ms = 20\n")
    path = tmp_path / DEPTH.name
    path.write_text(text + "\n[rig]\nwiring = { sync_period_ms = 20 }\n")
    assert load_profile(path).timing.control_period_ms == 20.0
    path.write_text(text)
    with pytest.raises(ConfigError, match="disagrees with the sowing_depth rig's 10 ms"):
        load_profile(path)
