"""Calibrate a flow controller's feedforward on the rig: the meter "rotation test".

Before sowing, an operator runs the metering shaft at fixed speeds with the tubes disconnected,
weighs what comes out and enters the ratio of weighed to expected mass into the controller
(every planter monitor has this step: the fertilizer of the day is not the one the meter's map
was fitted on). This script does the same on the emulated bench: it runs [F]'s constant-speed
baseline (the open-loop controller drives the shaft at the nominal map's speed for the target)
at the three bench rates, weighs the delivered mass (truth, as the scale does) and prints the
calibrated map coefficient, ``ff_coeff = 4.586 x weighed / expected``, for a profile's
``[parameters]``.

The runs use their own seeds (scenario seed + ``--seed-offset`` x repeat, default 100000,
200000, 300000), none of the
seeds a qualification uses by default or in the README's seed sweep: the calibration sees a
fertilizer lot of the same kind (the density deficit's mean), not the lot of the runs it is
judged on.

    python scripts/calibrate_meter.py [--seed-offset N] [--profile dut_profiles/...toml]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

from hil.dut.build import PROJECT_ROOT
from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.rig import RunOptions, load_rig, run_scenario

BASELINE = PROJECT_ROOT / "dut_profiles" / "fertilizer-open-loop-daemon.toml"
SCENARIOS = ("bench-constant-1150", "bench-constant-1700", "bench-constant-2200")
NOMINAL_FF_COEFF = 4.586  # [F]'s map q = 4.586 n^0.6537 g/s per row (rig.toml)


def weighed_over_expected(scenario_name: str, seed_offset: int, rig_from: Path) -> float:
    """One rotation test: weighed mass (delivered + still in the tubes) over the target."""
    rig = load_rig("fertilizer")
    scenario = rig.load_scenario(scenario_name)
    profile = load_profile(BASELINE)
    options = profile_run_options(profile, rig_from=load_profile(rig_from))
    with tempfile.TemporaryDirectory() as out:
        dut, _ = make_dut(profile, bus="inline", clock="lockstep")
        result = run_scenario(rig, scenario, dut,
                              RunOptions(out_dir=Path(out), bus="inline",
                                         seed=scenario.seed + seed_offset, **options))
    if result.record.get("error"):
        raise SystemExit(f"{scenario_name}: the run failed: {result.record['error']}")
    truth = result.record["truth"]
    weighed = float(truth["delivered_total_g"]) + float(sum(truth["in_transit_g"]))
    return weighed / (float(truth["target_mass_per_row_g"]) * len(truth["delivered_g"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed-offset", type=int, default=100000)
    parser.add_argument("--repeats", type=int, default=3,
                        help="each rate this many times (seed offsets N, 2N, ...), as an "
                             "operator repeats a rotation test")
    parser.add_argument("--profile", type=Path,
                        default=PROJECT_ROOT / "dut_profiles"
                        / "fertilizer-piecewise-pid-daemon.toml",
                        help="the profile whose [rig] the bench is set up with")
    args = parser.parse_args(argv)
    ratios = []
    for repeat in range(1, args.repeats + 1):
        for name in SCENARIOS:
            ratio = weighed_over_expected(name, args.seed_offset * repeat, args.profile)
            ratios.append(ratio)
            print(f"{name} (seed offset {args.seed_offset * repeat}): "
                  f"weighed / expected = {ratio:.4f}")
    factor = statistics.fmean(ratios)
    print(f"meter factor {factor:.4f} (spread {min(ratios):.4f}-{max(ratios):.4f})")
    print(f"ff_coeff = {NOMINAL_FF_COEFF * factor:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
