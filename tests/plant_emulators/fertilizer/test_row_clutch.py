"""Row clutches: a disengaged roller meters nothing, the others go on, both engines alike."""

from __future__ import annotations

import numpy as np
import pytest

from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fertilizer.physics import FertilizerPlant

pytest.importorskip("plant_emulators.fertilizer._plant_native",
                    reason="the C twins are not built (scripts/setup.sh builds them)")


def _run(engine: str) -> list[tuple[tuple[float, ...], tuple[float, ...], float]]:
    plant = FertilizerPlant(load_rig_config(), np.random.default_rng(3), engine=engine)
    plant.command_v = 5.0
    out = []
    for k in range(300):
        if k == 100:
            plant.engage_rows((True, False, True, True))
        if k == 200:
            plant.engage_rows((True, True, True, False))
        plant.advance(10, 0.001)
        out.append((plant.metered_g, plant.flow_at_meter_gps, plant.hopper_kg))
    return out


def test_a_disengaged_row_meters_nothing_and_the_engines_agree() -> None:
    native, python = _run("native"), _run("python")
    assert native == python
    metered = np.array([m for m, _, _ in python])
    # row 2 is out from step 100 to 199: it meters nothing then, and again after
    assert np.all(np.diff(metered[100:200, 1]) == 0.0)
    assert np.all(np.diff(metered[200:, 1]) > 0.0)
    # row 4 is out from step 200: nothing more; rows 1 and 3 meter throughout
    assert np.all(np.diff(metered[200:, 3]) == 0.0)
    assert np.all(np.diff(metered[:, 0]) > 0.0) and np.all(np.diff(metered[:, 2]) > 0.0)
    assert [f for f in python[-1][1]][3] == 0.0


def test_the_clutch_takes_one_flag_per_row() -> None:
    plant = FertilizerPlant(load_rig_config(), np.random.default_rng(3), engine="python")
    with pytest.raises(ValueError, match="3 clutch states for 4 rows"):
        plant.engage_rows((True, True, False))
