"""The isobus suite's VT tests discriminate: the ISOBUS reference with its operator interface
(``dut_profiles/fertilizer-piecewise-pid-isobus-vt-daemon.toml``) qualifies on them, and each VT
must-fail profile (``dut_profiles/must_fail/fertilizer-isobus-vt-*.toml``, the reference with a
``vt_defect``) fails them on the measurement its header names.

Each case is ``hil qualify PROFILE --bus inline -k <the VT tests that can see it>`` in a
subprocess, judged from its ``record.json``, as tests/test_discrimination_isobus.py does. A
qualification on a VT scenario takes tens of seconds, so all of them are ``slow``; the default
run checks the profiles here and the VT in the field run in process
(tests/hil/isobus/vt/test_field_vt.py).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.dut.profile import load_profile, must_fail_claims
from tests.helpers.hil_forkserver import HilForkServer
from tests.test_discrimination import _qualify

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-isobus-vt-daemon.toml"
MUST_FAIL = ROOT / "dut_profiles" / "must_fail"
NOT_PASSED = {"fail", "error"}
#: the VT tests (test_suites/fertilizer/test_vt.py)
VT_TESTS = "test_vt_"
VT_MEASUREMENTS = {"isobus.vt.connect.time_to_active", "isobus.vt.before_master.delivered",
                   "isobus.vt.master_off.stop_time", "isobus.vt.alarm.time_to_shown",
                   "isobus.vt.restart.reconnect_time", "isobus.vt.restart.uploaded_bytes",
                   "isobus.vt.calibration.initial_error"}

#: profile stem -> (-k selection, the measurement that must not pass)
EXPECTED: dict[str, tuple[str, str]] = {
    # Master off never stops the meters: they still turn at the end of the run (inf)
    "fertilizer-isobus-vt-ignores-master-daemon": ("test_vt_master_off",
                                                   "isobus.vt.master_off.stop_time"),
    # the lost row is never shown (inf)
    "fertilizer-isobus-vt-no-alarm-daemon": ("test_vt_alarm_on_row_loss",
                                             "isobus.vt.alarm.time_to_shown"),
    # end of object pool answered with an error: never active (inf)
    "fertilizer-isobus-vt-bad-pool-daemon": ("test_vt_connection",
                                             "isobus.vt.connect.time_to_active"),
    # never notices the VT went away, never active again (inf)
    "fertilizer-isobus-vt-no-reconnect-daemon": ("test_vt_restart",
                                                 "isobus.vt.restart.reconnect_time"),
    # lays the first pass's fertilizer before the operator's Master
    "fertilizer-isobus-vt-meters-without-vt-daemon": ("test_vt_nothing_before_master",
                                                      "isobus.vt.before_master.delivered"),
    # stored nothing: uploads its whole pool again after the VT's restart
    "fertilizer-isobus-vt-no-store-daemon": ("test_vt_restart",
                                             "isobus.vt.restart.uploaded_bytes"),
    # meters its own map: the lot's +8 % from the start
    "fertilizer-isobus-vt-ignores-calibration-daemon": ("test_vt_calibration",
                                                        "isobus.vt.calibration.initial_error"),
    # working set maintenance every 2 s: the bus conformance of its run
    "fertilizer-isobus-vt-slow-maintenance-daemon": ("test_vt_connection",
                                                     "isobus.vt_client.violations"),
}


def test_every_vt_must_fail_profile_is_checked_here_as_its_header_says() -> None:
    reference = load_profile(REFERENCE)
    profiles = sorted(MUST_FAIL.glob("fertilizer-isobus-vt-*.toml"))
    assert sorted(p.stem for p in profiles) == sorted(EXPECTED)
    for path in profiles:
        profile = load_profile(path)
        assert profile.wiring.isobus and profile.limits == reference.limits, path.name
        assert profile.rig_config == reference.rig_config, path.name
        assert profile.launch.inprocess == reference.launch.inprocess, path.name
        defect = path.stem.removeprefix("fertilizer-isobus-vt-").removesuffix("-daemon")
        assert profile.parameters == {**reference.parameters, "vt_defect": defect}, path.name
        assert must_fail_claims(path) == {EXPECTED[path.stem][1]}, path.name


@pytest.mark.slow
def test_the_vt_reference_qualifies_on_the_operator_run(tmp_path: Path,
                                                        hil_forked: HilForkServer) -> None:
    """The VT tests of the one operator run (connection, nothing before Master, Master off,
    the alarm), and its VT-client conformance: 69 s on the loaded host, so slow;
    the default run's form is tests/hil/isobus/vt/test_field_vt.py (the same reference, VT
    and operator in process, ~1 s)."""
    proc, record = _qualify(hil_forked, REFERENCE, tmp_path / "q",
                            f"{VT_TESTS} and not restart and not calibration")
    assert proc.returncode == 0 and record["verdict"] == "pass", proc.stdout + proc.stderr
    judged = [m for m in record["measurements"] if m["outcome"] != "info"]
    assert judged and all(m["outcome"] == "pass" for m in judged), [
        (m["name"], m["value"], m["outcome"]) for m in judged if m["outcome"] != "pass"]
    names = {m["name"] for m in judged}
    assert VT_MEASUREMENTS - {"isobus.vt.restart.reconnect_time",
                              "isobus.vt.restart.uploaded_bytes",
                              "isobus.vt.calibration.initial_error"} <= names
    kinds = {m["conditions"]["kind"] for m in judged
             if m["name"] == "isobus.vt_client.violations"}
    assert kinds == {"maintenance", "pool-before-memory", "two-transfers"}


@pytest.mark.slow
def test_the_vt_reference_qualifies_on_every_vt_test(tmp_path: Path,
                                                     hil_forked: HilForkServer) -> None:
    proc, record = _qualify(hil_forked, REFERENCE, tmp_path / "q", VT_TESTS)
    assert proc.returncode == 0 and record["verdict"] == "pass", proc.stdout + proc.stderr
    judged = [m for m in record["measurements"] if m["outcome"] != "info"]
    assert {m["name"] for m in judged} >= VT_MEASUREMENTS
    assert all(m["outcome"] == "pass" for m in judged)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_vt_must_fail_profile_fails_on_its_defect(tmp_path: Path, name: str,
                                                 hil_forked: HilForkServer) -> None:
    selection, measurement = EXPECTED[name]
    proc, record = _qualify(hil_forked, MUST_FAIL / f"{name}.toml", tmp_path / "q", selection)
    assert proc.returncode == 1 and record["verdict"] == "fail", proc.stdout + proc.stderr
    got = [m for m in record["measurements"] if m["name"] == measurement]
    assert got, f"{name}: {measurement} was not measured"
    bad = [m for m in got if m["outcome"] in NOT_PASSED]
    # one condition at least (the conformance's per kind: the maintenance one)
    assert bad, [(m["conditions"], m["value"], m["outcome"], m["note"]) for m in got]
