"""[F] accuracy: bench constant runs (1,150 / 1,700 / 2,200 g over 50 s) and field runs
(4 / 6 / 8 km/h, 60 s, M = 200 kg/hm2, D = 3 m), judged by eq. 15 against the weighed mass.

The fast suite runs each condition once; the full suite adds [F]'s second and third repeats
(other seeds: other noise, density drift and row spread).
"""

from __future__ import annotations

import pytest

from hil.metrics import accuracy_theta
from test_suites.fertilizer.traces import delivered_and_target_g

pytestmark = pytest.mark.hil_rig("fertilizer")

BENCH_G = (1150, 1700, 2200)
FIELD_KMH = (4, 6, 8)
REPEAT_SEED_STEP = 1000


def _repeats(first_suite: str) -> list[pytest.param]:
    return [pytest.param(1, marks=pytest.mark.hil_suite(first_suite)),
            pytest.param(2, marks=[pytest.mark.hil_suite("full"), pytest.mark.slow]),
            pytest.param(3, marks=[pytest.mark.hil_suite("full"), pytest.mark.slow])]


def _seed(rig, scenario: str, repeat: int) -> int:
    return rig.load_scenario(scenario).seed + REPEAT_SEED_STEP * (repeat - 1)


@pytest.mark.parametrize("repeat", _repeats("fast"))
@pytest.mark.parametrize("target_g", BENCH_G)
def test_bench_accuracy(hil_run, hil_rig, hil_measure, target_g: int, repeat: int) -> None:
    scenario = f"bench-constant-{target_g}"
    result = hil_run(scenario, seed=_seed(hil_rig, scenario, repeat), label=f"r{repeat}")
    delivered, target = delivered_and_target_g(result)
    hil_measure("flow.bench.accuracy", accuracy_theta(target, delivered),
                conditions={"target_g": target_g, "repeat": repeat}, run=result,
                note=f"weighed {delivered:.1f} g of {target:.1f} g")


@pytest.mark.parametrize("repeat", _repeats("fast"))
@pytest.mark.parametrize("speed_kmh", FIELD_KMH)
def test_field_accuracy(hil_run, hil_rig, hil_measure, speed_kmh: int, repeat: int) -> None:
    scenario = f"field-{speed_kmh}kmh"
    result = hil_run(scenario, seed=_seed(hil_rig, scenario, repeat), label=f"r{repeat}")
    delivered, target = delivered_and_target_g(result)
    hil_measure("flow.field.accuracy", accuracy_theta(target, delivered),
                conditions={"speed_kmh": speed_kmh, "repeat": repeat}, run=result,
                note=f"weighed {delivered:.1f} g of {target:.1f} g")
