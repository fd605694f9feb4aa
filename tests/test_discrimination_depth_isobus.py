"""The depth rig's isobus suite discriminates: the ISOBUS depth reference follows the map's
zones, and the must-fail that holds one depth whatever the TC sends fails the zones it is not
in, on isobus.depth.zone_error (each qualification ~2-5 min of a 140 s field run: slow).

Each ISOBUS depth must-fail (``dut_profiles/must_fail/sowing-depth-isobus-*.toml``) fails on
the measurement its defect breaks, with ``-k`` to the tests that can see it (:data:`EXPECTED`);
the default run checks only that every profile is here as its header says (no run)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from hil.dut.profile import load_profile, must_fail_claims

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-isobus-daemon.toml"
MUST_FAIL = ROOT / "dut_profiles" / "must_fail"
IGNORES_MAP = MUST_FAIL / "sowing-depth-isobus-ignores-map-daemon.toml"
NOT_PASSED = {"fail", "error"}

#: profile stem -> (-k selection, measurement -> the conditions (as "k=v, ..." of the
#: measurement's conditions; "" for none) that must not pass)
EXPECTED: dict[str, tuple[str, dict[str, set[str]]]] = {
    # holds 30 mm: the 35 and 40 mm zones are off; no boundary into them is ever settled
    "sowing-depth-isobus-ignores-map-daemon": (
        "follows_the_map or zone_transitions",
        {"isobus.depth.zone_error": {"zone=35 mm", "zone=40 mm"},
         "isobus.depth.zone_pass_rate": {"zone=40 mm"},
         "isobus.depth.transition_distance": {""}}),
    # says 40, then 35 mm while the jammed rod keeps the seeds at ~30 mm
    "sowing-depth-isobus-reports-setpoint-daemon": (
        "drive_jammed",
        {"isobus.depth.reported_error": {"scenario=isobus-depth-drive-jammed, zone=40 mm",
                                         "scenario=isobus-depth-drive-jammed, zone=35 mm"}}),
    # keeps the TC's 40 mm after the TC is lost instead of the declared 30 mm
    "sowing-depth-isobus-never-falls-back-daemon": (
        "tc_loss", {"isobus.depth.tc_loss.fallback_time": {""}}),
    # its last velocity command goes on when the tractor stops
    "sowing-depth-isobus-holds-command-at-standstill-daemon": (
        "after_the_speed_loss",
        {"isobus.depth.speed_loss.rod_travel": {"scenario=isobus-depth-speed-loss"}}),
}


def _qualify(profile: Path, out: Path, selection: str | None = None) -> tuple[int, dict]:
    proc = subprocess.run([sys.executable, "-m", "hil", "qualify", str(profile), "--bus",
                           "inline", "--out", str(out), "--quiet",
                           *(["-k", selection] if selection else [])], cwd=ROOT,
                          capture_output=True, text=True, timeout=1800)
    record = out / "record.json"
    assert record.exists(), proc.stdout + proc.stderr
    return proc.returncode, json.loads(record.read_text())


def _zones(record: dict, name: str) -> dict[str, str]:
    return {m["conditions"]["zone"]: m["outcome"] for m in record["measurements"]
            if m["name"] == name}


def _label(conditions: dict) -> str:
    return ", ".join(f"{k}={v}" for k, v in sorted(conditions.items()))


def test_every_depth_isobus_must_fail_is_checked_here_as_its_header_says() -> None:
    reference = load_profile(REFERENCE)
    profiles = sorted(MUST_FAIL.glob("sowing-depth-isobus-*.toml"))
    assert sorted(p.stem for p in profiles) == sorted(EXPECTED)
    for path in profiles:
        profile = load_profile(path)
        assert profile.wiring.isobus and profile.limits == reference.limits, path.name
        assert profile.rig_config == reference.rig_config, path.name
        assert must_fail_claims(path) == set(EXPECTED[path.stem][1]), path.name


@pytest.mark.slow
def test_the_reference_follows_every_zone(tmp_path: Path) -> None:
    code, record = _qualify(REFERENCE, tmp_path / "ref")
    assert code == 0 and record["verdict"] == "pass"
    assert _zones(record, "isobus.depth.zone_error") == {
        "30 mm": "pass", "35 mm": "pass", "40 mm": "pass"}
    assert set(_zones(record, "isobus.depth.zone_pass_rate").values()) == {"pass"}
    # the report draws the depth prescription and the as-sown depth of each field run
    html = (tmp_path / "ref" / "report.html").read_text(encoding="utf-8")
    section = html[html.index('<section id="field-maps">'):]
    assert "<th>sown (mm)</th>" in section
    assert section[:section.index("</section>")].count("<img ") == 4     # the four runs


@pytest.mark.slow
def test_holding_one_depth_fails_the_other_zones(tmp_path: Path) -> None:
    code, record = _qualify(IGNORES_MAP, tmp_path / "bad", EXPECTED[IGNORES_MAP.stem][0])
    assert code == 1 and record["verdict"] == "fail"
    assert _zones(record, "isobus.depth.zone_error") == {
        "30 mm": "pass", "35 mm": "fail", "40 mm": "fail"}
    assert _zones(record, "isobus.depth.zone_pass_rate")["40 mm"] == "fail"
    assert [m["outcome"] for m in record["measurements"]
            if m["name"] == "isobus.depth.transition_distance"] == ["fail"]


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(set(EXPECTED) - {IGNORES_MAP.stem}))
def test_depth_isobus_must_fail_fails_on_its_defect(tmp_path: Path, name: str) -> None:
    selection, expected = EXPECTED[name]
    code, record = _qualify(MUST_FAIL / f"{name}.toml", tmp_path / "q", selection)
    assert code == 1 and record["verdict"] == "fail"
    for measurement, conditions in expected.items():
        got = {_label(m["conditions"]): m for m in record["measurements"]
               if m["name"] == measurement}
        assert got, f"{name}: {measurement} was not measured"
        for label in conditions:
            assert label in got, f"{name}: {measurement} has no {label!r}: {sorted(got)}"
            m = got[label]
            assert m["outcome"] in NOT_PASSED, (
                f"{name}: {measurement} {label} = {m['value']} {m['outcome']}")


@pytest.mark.slow
def test_the_reference_passes_the_fault_runs(tmp_path: Path) -> None:
    """The reference on the runs the must-fails fail (the field run: above)."""
    selection = " or ".join(sorted({EXPECTED[n][0] for n in EXPECTED} - {
        EXPECTED[IGNORES_MAP.stem][0]}))
    code, record = _qualify(REFERENCE, tmp_path / "ref", selection)
    assert code == 0 and record["verdict"] == "pass"
    names = {m["name"] for m in record["measurements"]}
    assert {"isobus.depth.reported_error", "isobus.depth.tc_loss.fallback_time",
            "isobus.depth.speed_loss.rod_travel"} <= names
