"""The isobus suite discriminates: the ISOBUS reference qualifies on it, and each ISOBUS
must-fail profile (``dut_profiles/must_fail/fertilizer-isobus-*.toml``) fails it on the
measurement its defect breaks.

Each case is ``hil qualify PROFILE --bus inline`` in a subprocess (``-k`` to the tests that can
see the defect), judged from its ``record.json``, as tests/test_discrimination.py does for the
terminal suites.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from hil.dut.profile import load_profile, must_fail_claims
from tests.helpers.hil_forkserver import HilForkServer
from tests.test_discrimination import _qualify

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-isobus-daemon.toml"
MUST_FAIL = ROOT / "dut_profiles" / "must_fail"
NOT_PASSED = {"fail", "error"}

#: profile stem -> (-k selection, measurement -> how many of its conditions must not pass)
EXPECTED: dict[str, tuple[str, dict[str, int]]] = {
    # 200 kg/ha everywhere: the 160 and 240 zones are off by 25 % and 17 %; no new rate ever
    "fertilizer-isobus-ignores-map-daemon": ("rate_per_zone or zone_transitions",
                                             {"isobus.field.rate_accuracy": 2,
                                              "isobus.zone.transition_distance": 1}),
    # rows 3 and 4 stay on over the overlapping pass
    "fertilizer-isobus-never-switches-daemon": ("section_switching",
                                                {"isobus.section.switch_error": 1,
                                                 "isobus.section.overlap_per_switch": 1}),
    # every row stays off from the headland it starts in: nothing is applied
    "fertilizer-isobus-latches-sections-off-daemon": ("section_switching",
                                                      {"isobus.section.skip_per_switch": 1}),
    # the wheel-based speed over-reads by the 5 % slip: every zone over-applied
    "fertilizer-isobus-wheel-speed-daemon": ("rate_per_zone",
                                             {"isobus.field.rate_accuracy": 3}),
    # a frame from its address before the claim, in every run (the conformance of each)
    "fertilizer-isobus-sends-before-claim-daemon": ("tc_refuses",
                                                    {"isobus.claim.frames_before": 1}),
    # the TC refuses the pool: never active
    "fertilizer-isobus-broken-ddop-daemon": ("connection",
                                             {"isobus.connect.time_to_active": 1}),
    # meters while the TC is gone and when it refuses the pool
    "fertilizer-isobus-meters-without-tc-daemon": ("tc_restart or tc_refuses",
                                                   {"isobus.tc.loss.delivered": 1,
                                                    "isobus.tc.refused.delivered": 1}),
    # never connects again after the TC's restart
    "fertilizer-isobus-never-reconnects-daemon": ("tc_restart",
                                                  {"isobus.tc.restart.reconnect_time": 1}),
    # keeps its last speed when the TECU falls silent at 8 km/h; the tractor slows to 3 km/h
    "fertilizer-isobus-holds-speed-daemon": ("speed_loss",
                                             {"isobus.tecu.speed_loss.overapplication": 1}),
}

#: qualified in the default run (short runs, two kinds of defect: bus protocol, a fault);
#: the others run with ``-m slow``
FAST_SUBSET = {"fertilizer-isobus-sends-before-claim-daemon",
               "fertilizer-isobus-holds-speed-daemon"}


def test_every_isobus_must_fail_profile_is_checked_here_as_its_header_says() -> None:
    reference = load_profile(REFERENCE)
    # the VT implements (fertilizer-isobus-vt-*) are judged by tests/test_discrimination_vt.py
    profiles = sorted(p for p in MUST_FAIL.glob("fertilizer-isobus-*.toml")
                      if not p.stem.startswith("fertilizer-isobus-vt-"))
    assert sorted(p.stem for p in profiles) == sorted(EXPECTED)
    for path in profiles:
        profile = load_profile(path)
        assert profile.wiring.isobus and profile.limits == reference.limits, path.name
        assert profile.rig_config == reference.rig_config, path.name
        assert must_fail_claims(path) == set(EXPECTED[path.stem][1]), path.name


def test_the_isobus_reference_qualifies_on_the_isobus_suite(tmp_path: Path,
                                                            hil_forked: HilForkServer) -> None:
    proc, record = _qualify(hil_forked, REFERENCE, tmp_path / "q", None)
    assert proc.returncode == 0 and record["verdict"] == "pass", proc.stdout + proc.stderr
    assert record["suites"] == ["isobus"]      # chosen for [wiring] isobus = true
    names = {m["name"] for m in record["measurements"]}
    assert {"isobus.connect.time_to_active", "isobus.field.rate_accuracy",
            "isobus.zone.transition_distance", "isobus.section.switch_error",
            "isobus.tc.restart.reconnect_time", "isobus.tc.loss.delivered",
            "isobus.tc.refused.delivered", "isobus.tecu.speed_loss.overapplication",
            "isobus.claim.frames_before", "isobus.transport.violations"} <= names
    judged = [m for m in record["measurements"] if m["outcome"] != "info"]
    assert judged and all(m["outcome"] == "pass" for m in judged)


@pytest.mark.parametrize("name", [
    name if name in FAST_SUBSET else pytest.param(name, marks=pytest.mark.slow)
    for name in sorted(EXPECTED)])
def test_isobus_must_fail_profile_fails_on_its_defect(tmp_path: Path, name: str,
                                                     hil_forked: HilForkServer) -> None:
    selection, expected = EXPECTED[name]
    proc, record = _qualify(hil_forked, MUST_FAIL / f"{name}.toml", tmp_path / "q", selection)
    assert proc.returncode == 1 and record["verdict"] == "fail", proc.stdout + proc.stderr
    for measurement, at_least in expected.items():
        got = [m for m in record["measurements"] if m["name"] == measurement]
        assert got, f"{name}: {measurement} was not measured"
        bad = [m for m in got if m["outcome"] in NOT_PASSED]
        assert len(bad) >= at_least, (
            f"{name}: {measurement} failed {len(bad)} of {len(got)} conditions, expected at "
            f"least {at_least}: " + "; ".join(f"{m['conditions']} = {m['value']} "
                                              f"{m['outcome']}" for m in got))


@pytest.mark.slow
@pytest.mark.parametrize("profile", ["fertilizer-piecewise-pid-isobus-daemon",
                                     "fertilizer-piecewise-pid-isobus-firmware"])
def test_the_isobus_references_qualify_in_real_time_on_the_software_bus(tmp_path: Path,
                                                                       profile: str) -> None:
    """The runs' own length (~4.5 min each): the tractor, the TC and the implement on their
    own clocks, the implement a process of its own (the firmware's socketcand HAL)."""
    out = tmp_path / "q"
    proc = subprocess.run(
        [sys.executable, "-m", "hil", "qualify", f"dut_profiles/{profile}.toml", "--bus",
         "softbus", "--clock", "realtime", "--out", str(out), "--quiet"],
        capture_output=True, text=True, cwd=ROOT, timeout=1200)
    record = json.loads((out / "record.json").read_text())
    if record["verdict"] == "invalid-bench":
        pytest.skip("invalid bench (real-time timing on a loaded host): " + proc.stdout[-300:])
    assert proc.returncode == 0 and record["verdict"] == "pass", proc.stdout + proc.stderr
