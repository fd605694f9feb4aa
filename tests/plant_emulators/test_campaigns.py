"""Full field campaigns in lockstep: long, so marked ``slow`` (CI runs them nightly with
``-m ""``). They check that whole runs complete and that the truth lands near the papers with the
rigs' minimal built-in controllers; the qualification suites judge real controllers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.dut import InProcessDut
from hil.rig import RunOptions, run_scenario
from plant_emulators.fertilizer.controllers import PiFlowController
from plant_emulators.fertilizer.rig import FertilizerRig
from plant_emulators.sowing_depth.controllers import PiDepthController
from plant_emulators.sowing_depth.rig import SowingDepthRig
from plant_emulators.sowing_depth.sampling import paper_sample

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("kmh", [4, 6, 8])
def test_fertilizer_field_run(tmp_path: Path, kmh: int) -> None:
    scenario = FertilizerRig.load_scenario(f"field-{kmh}kmh")
    run = run_scenario(FertilizerRig, scenario, InProcessDut(PiFlowController()),
                       RunOptions(out_dir=tmp_path))
    truth = run.record["truth"]
    target = truth["target_mass_per_row_g"] * 4
    got = truth["delivered_total_g"] + sum(truth["in_transit_g"])
    accuracy = 100.0 * (1.0 - abs(got - target) / target)   # [F] eq. 15
    print(f"\nfield {kmh} km/h: delivered {got:.0f} g of {target:.0f} g, theta {accuracy:.2f} %")
    assert run.record["error"] is None
    assert accuracy > 94.0


@pytest.mark.parametrize("band", ["1-3", "3-5", "5-7"])
def test_sowing_depth_field_run(tmp_path: Path, band: str) -> None:
    scenario = SowingDepthRig.load_scenario(f"field-{band}kmh")
    run = run_scenario(SowingDepthRig, scenario, InProcessDut(PiDepthController()),
                       RunOptions(out_dir=tmp_path))
    assert run.record["error"] is None
    truth = np.load(tmp_path / "truth.npz")
    x = truth["distance_m"]
    plot = (x >= 10.0) & (x <= 170.0)            # 10 m headlands excluded, as [D]
    depth = truth["depth_mm"][plot]
    inlier = truth["outlier_kind"][plot] == 0
    pass_rate = 100.0 * (np.abs(depth - 30.0) <= 10.0).mean()
    cv = 100.0 * depth[inlier].std(ddof=1) / depth[inlier].mean()
    print(f"\nfield {band} km/h: mean {depth.mean():.2f} mm, pass {pass_rate:.1f} %, "
          f"inlier CV {cv:.2f} % over {depth.size} seed positions")
    assert x[-1] >= 180.0
    assert depth.mean() == pytest.approx(30.0, abs=2.5)
    assert 85.0 < pass_rate < 97.0
    assert 2.0 < cv < 5.0
    sampled = paper_sample(x, truth["depth_mm"], np.random.default_rng(0))   # 3 rows x 40
    sampled_pass = 100.0 * (np.abs(sampled - 30.0) <= 10.0).mean()
    print(f"  sampled as [D] (3 x 40): mean {sampled.mean():.2f} mm, pass {sampled_pass:.1f} %")
    assert sampled.shape == (3, 40) and 80.0 <= sampled_pass <= 100.0
