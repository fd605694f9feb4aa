"""Benchmark: how the fertilizer physics' cost grows with the number of rows (4 → 48).

Physics only: the rig's bus side has four flow modules in its DBC (FlowModule1-4), so a
48-row rig on the bus needs a generated DBC first (not built). The node ids of the extra
rows are placeholders (the physics does not read them). Prints µs per 1 kHz step and the
real-time factor of the physics alone::

    python -m pytest benchmarks/bench_scale.py -s
"""

from __future__ import annotations

import numpy as np
import pytest

from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fertilizer.physics import FertilizerPlant

DT = 0.001
STEPS = 10_000


def _plant(rows: int, engine: str) -> FertilizerPlant:
    ids = [i for i in range(33, 33 + rows)]          # clear of the rig's own nodes 5, 16, 32
    cfg = load_rig_config(overrides={"meter": {"rows": rows},
                                     "wiring": {"flow_module_node_ids": ids}})
    plant = FertilizerPlant(cfg, np.random.default_rng(1), engine=engine)
    plant.command_v = 3.5                            # 21 r/min: every row delivering
    plant.advance(2000, DT)
    return plant


@pytest.mark.parametrize("engine", ["native", "python"])
@pytest.mark.parametrize("rows", [4, 12, 24, 48])
def test_physics_cost_per_row(benchmark, timed_rounds, rows: int, engine: str) -> None:
    plant = _plant(rows, engine)

    def ten_seconds() -> None:
        for _ in range(STEPS // 100):
            plant.advance(100, DT)

    benchmark.pedantic(ten_seconds, rounds=3, iterations=1)
    assert all(np.isfinite(plant.flow_at_meter_gps)) and len(plant.flow_at_meter_gps) == rows
    us = min(timed_rounds()) / STEPS * 1e6
    benchmark.extra_info.update({"rows": rows, "engine": engine, "us_per_step": round(us, 3)})
    print(f"\nfertilizer physics ({engine}), {rows:2d} rows: {us:6.2f} us per 1 kHz step, "
          f"x{1e6 / us / 1000:,.0f} real time (physics alone)")
