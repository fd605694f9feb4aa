"""The depth rig's isobus suite discriminates: the ISOBUS depth reference follows the map's
zones, and the must-fail that holds one depth whatever the TC sends fails the zones it is not
in, on isobus.depth.zone_error (each qualification ~2-5 min of a 140 s field run: slow)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from hil.dut.profile import must_fail_claims

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-isobus-daemon.toml"
IGNORES_MAP = ROOT / "dut_profiles" / "must_fail" / "sowing-depth-isobus-ignores-map-daemon.toml"


def _qualify(profile: Path, out: Path) -> tuple[int, dict]:
    proc = subprocess.run([sys.executable, "-m", "hil", "qualify", str(profile), "--bus",
                           "inline", "--out", str(out), "--quiet"], cwd=ROOT,
                          capture_output=True, text=True, timeout=1200)
    record = out / "record.json"
    assert record.exists(), proc.stdout + proc.stderr
    return proc.returncode, json.loads(record.read_text())


def _zones(record: dict, name: str) -> dict[str, str]:
    return {m["conditions"]["zone"]: m["outcome"] for m in record["measurements"]
            if m["name"] == name}


def test_the_must_fail_names_what_it_fails() -> None:
    assert must_fail_claims(IGNORES_MAP) == {"isobus.depth.zone_error",
                                            "isobus.depth.zone_pass_rate"}


@pytest.mark.slow
def test_the_reference_follows_every_zone(tmp_path: Path) -> None:
    code, record = _qualify(REFERENCE, tmp_path / "ref")
    assert code == 0 and record["verdict"] == "pass"
    assert _zones(record, "isobus.depth.zone_error") == {
        "30 mm": "pass", "35 mm": "pass", "40 mm": "pass"}
    assert set(_zones(record, "isobus.depth.zone_pass_rate").values()) == {"pass"}


@pytest.mark.slow
def test_holding_one_depth_fails_the_other_zones(tmp_path: Path) -> None:
    code, record = _qualify(IGNORES_MAP, tmp_path / "bad")
    assert code == 1 and record["verdict"] == "fail"
    assert _zones(record, "isobus.depth.zone_error") == {
        "30 mm": "pass", "35 mm": "fail", "40 mm": "fail"}
    assert _zones(record, "isobus.depth.zone_pass_rate")["40 mm"] == "fail"
