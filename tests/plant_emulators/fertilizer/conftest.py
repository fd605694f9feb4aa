"""Fixtures for the fertilizer rig's model tests."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from plant_emulators.fertilizer.config import FertilizerRigConfig, load_rig_config


@pytest.fixture(scope="session")
def rig_config() -> FertilizerRigConfig:
    """The packaged rig configuration."""
    return load_rig_config()


@pytest.fixture(scope="session")
def calibrated_config(rig_config: FertilizerRigConfig) -> FertilizerRigConfig:
    """The rig at its calibration condition: nominal rollers, calibration fertilizer, full box.

    Pulsation is kept (it averages out over whole flute periods); only the deviations from the
    calibrated map (row spread, drift, flute-charge noise, hopper level) are removed.
    """
    c = rig_config
    return dataclasses.replace(
        c,
        meter=dataclasses.replace(c.meter, row_spread_sd_frac=0.0, flute_charge_sd_frac=0.0),
        fertilizer=dataclasses.replace(
            c.fertilizer, density_offset_mean_frac=0.0, density_offset_sd_frac=0.0,
            density_drift_sd_frac=0.0,
            hopper_initial_kg=c.fertilizer.hopper_capacity_kg),
    )


@pytest.fixture
def rng() -> np.random.Generator:
    """A fresh generator with a fixed seed."""
    return np.random.default_rng(20230203)
