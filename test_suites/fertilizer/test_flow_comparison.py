"""[F]'s comparison with the constant-speed baseline: the same bench runs (same seeds, so the
same meter, density drift and sensor noise) with the reference open-loop controller.

The measurement is the DUT's mean bench accuracy minus the baseline's, in percentage points
([F]: 98.14 % against 95.10 %). A flow controller that does not beat a constant-speed meter
has no reason to exist.
"""

from __future__ import annotations

import pytest

from hil.dut.build import PROJECT_ROOT
from hil.dut.profile import load_profile
from hil.metrics import accuracy_theta
from test_suites.fertilizer.test_flow_accuracy import BENCH_G
from test_suites.fertilizer.traces import delivered_and_target_g

pytestmark = pytest.mark.hil_rig("fertilizer")

BASELINE = PROJECT_ROOT / "dut_profiles" / "fertilizer-open-loop-daemon.toml"


@pytest.mark.hil_suite("fast")
def test_accuracy_gain_over_constant_speed(hil_run, hil_measure) -> None:
    baseline = load_profile(BASELINE)
    dut_theta, base_theta = [], []
    for target_g in BENCH_G:
        scenario = f"bench-constant-{target_g}"
        dut = hil_run(scenario)
        dut_theta.append(accuracy_theta(*reversed(delivered_and_target_g(dut))))
        if dut.record.get("error"):
            hil_measure("flow.comparison.accuracy_gain", float("nan"), run=dut)
            return
        base = hil_run(scenario, profile=baseline, bus="inline", label=f"baseline-{target_g}")
        delivered, target = delivered_and_target_g(base)
        if not delivered > 0.5 * target:
            # a constant-speed meter delivers about its target whatever the DUT: nothing means
            # the baseline never ran (the rig spoke to it in another bus layout), and a gain over
            # it would pass any DUT
            hil_measure("flow.comparison.accuracy_gain", float("nan"), run=base,
                        note=f"the constant-speed baseline delivered {delivered:.1f} g of "
                             f"{target:.1f} g at {scenario}: no comparison")
            return
        base_theta.append(accuracy_theta(target, delivered))
    gain = sum(dut_theta) / len(dut_theta) - sum(base_theta) / len(base_theta)
    hil_measure("flow.comparison.accuracy_gain", gain,
                note="DUT " + " / ".join(f"{v:.2f}" for v in dut_theta) + " %; constant speed "
                     + " / ".join(f"{v:.2f}" for v in base_theta) + " %")
