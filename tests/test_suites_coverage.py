"""The general rule of the suites (issue 21): every measurement in the catalogue
(``hil/limits.py``) can fail, and something shows that it does.

A measurement is *covered* when at least one must-fail DUT profile names it in a header line

    # must-fail: flow.fault.speed_loss.overdelivery, flow.bench.accuracy

(any ``dut_profiles/must_fail/**/*.toml``, the bus-defect ones in ``must_fail/bus/`` too;
the discrimination tests run those profiles and check that each fails there:
``tests/test_discrimination.py``, ``tests/test_suites_depth_*.py``,
and the bus-conformance tests for ``*-bus-*`` profiles), or when :data:`SYNTHETIC` names the
framework test whose synthetic DUT or data fails it. This test enumerates the catalogue, so
a new measurement without either fails the build; so does a registration naming a
measurement the catalogue does not have.

:data:`GAPS` lists the measurements that nothing fails yet, each with the reason: the list
may only shrink (a covered measurement left in it fails too).
"""

from __future__ import annotations

from pathlib import Path

from hil.dut.profile import must_fail_claims
from hil.limits import BUILT_IN, MEASUREMENTS

ROOT = Path(__file__).resolve().parents[1]
MUST_FAIL = ROOT / "dut_profiles" / "must_fail"

#: measurement -> the framework test that fails it with a synthetic DUT or synthetic data
SYNTHETIC: dict[str, str] = {
    "bus.share": "tests/hil/conformance/test_checks.py::"
                 "test_judge_fails_a_dut_that_takes_too_much_of_the_bus",
    "bus.heartbeat.max_interval": "tests/hil/conformance/test_checks.py::"
                                  "test_judge_fails_a_heartbeat_gap_longer_than_the_consumer_time",
    "bus.sync_latency.p99": "tests/hil/conformance/test_checks.py::"
                            "test_judge_fails_a_dut_that_misses_sync_answers_in_real_time",
    # ISOBUS conformance: synthetic frame logs of a defective stack (issue 27)
    "isobus.claim.request_answered": "tests/hil/conformance/test_isobus_conformance.py::"
                                     "test_a_request_for_address_claimed_left_unanswered_fails",
    "isobus.claim.contention": "tests/hil/conformance/test_isobus_conformance.py::"
                               "test_a_dut_that_keeps_its_address_after_losing_it_fails",
    "isobus.transport.violations": "tests/hil/conformance/test_isobus_conformance.py::"
                                   "test_a_tp_sender_that_ignores_cts_fails",
    "isobus.pgn.rate": "tests/hil/conformance/test_isobus_conformance.py::"
                       "test_a_cyclic_pgn_off_its_declared_period_fails",
}

#: measurement -> why no must-fail profile or synthetic DUT fails it yet (issue 21's rule is
#: not met for these; the list may only shrink)
GAPS: dict[str, str] = {
    "depth.field.cv": "information: GB/T 20865's CV over every sample, outliers included "
                      "(pass_rate and inlier_cv carry the field limits, papers.md on [D] "
                      "Table 3); no limit in the profiles, so it cannot fail in the suites "
                      "(the gate judges its regression against a baseline)",
    "bus.sync_latency.p50": "information: the median of the SYNC-to-command latency in real "
                            "time, recorded with no limit (bus.sync_latency.p99 carries the "
                            "limit, the control period); the report shows the distribution",
    "bus.sync_latency.max": "information: the largest SYNC-to-command latency in real time, "
                            "recorded with no limit (one late answer on a shared host is the "
                            "bench's as often as the DUT's; p99 carries the limit)",
    "rig.timing.lateness_p99": "judges the bench, not the DUT (a late rig makes the run "
                               "invalid bench); no limit in the profiles",
}


def registered() -> dict[str, list[str]]:
    """measurement -> the must-fail profiles (file names) whose header names it."""
    out: dict[str, list[str]] = {}
    for path in sorted(MUST_FAIL.rglob("*.toml")):
        for name in sorted(must_fail_claims(path)):
            out.setdefault(name, []).append(path.name)
    return out


def test_registrations_name_catalogue_measurements() -> None:
    unknown = {name: files for name, files in registered().items()
               if name not in MEASUREMENTS}
    unknown.update({name: [test] for name, test in SYNTHETIC.items()
                    if name not in MEASUREMENTS})
    assert not unknown, f"registered measurements not in hil/limits.py: {unknown}"


def test_every_catalogue_measurement_can_be_failed() -> None:
    covered = set(registered()) | set(SYNTHETIC)
    # the built-in catalogue (a rig of your own loaded earlier in this process adds its own,
    # whose must-fail is its worked example's: tests/test_docs_example_own_rig.py)
    missing = sorted(BUILT_IN - covered - set(GAPS))
    assert not missing, ("measurements no must-fail profile (`# must-fail:` header) or "
                         f"synthetic DUT (SYNTHETIC) fails: {missing}")


def test_gaps_only_shrink() -> None:
    closed = sorted(set(GAPS) & (set(registered()) | set(SYNTHETIC)))
    assert not closed, f"covered now, remove from GAPS: {closed}"
    stale = sorted(set(GAPS) - set(MEASUREMENTS))
    assert not stale, f"GAPS names measurements the catalogue no longer has: {stale}"


def test_every_must_fail_profile_says_what_it_must_fail() -> None:
    silent = [p.name for p in sorted(MUST_FAIL.glob("*.toml"))
              if not must_fail_claims(p)]
    assert not silent, f"must-fail profiles without a '# must-fail:' header: {silent}"


def test_synthetic_entries_name_existing_tests() -> None:
    """A SYNTHETIC entry must point at a test that exists (a renamed test would leave the
    measurement covered by nothing)."""
    for name, test in SYNTHETIC.items():
        path, _, function = test.partition("::")
        source = (ROOT / path).read_text(encoding="utf-8")
        assert f"def {function}(" in source, f"{name}: {test} does not exist"
