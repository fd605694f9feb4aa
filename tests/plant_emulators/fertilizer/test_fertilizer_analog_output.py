"""C-3402 output stage: scaling, clipping, DAC resolution, error value."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from plant_emulators.fertilizer.analog_output import AnalogOutputChannel


@pytest.fixture
def ideal(rig_config) -> AnalogOutputChannel:
    cfg = dataclasses.replace(rig_config.analog_output, gain_error_sd_frac=0.0,
                              offset_error_sd_mv=0.0)
    return AnalogOutputChannel(cfg, np.random.default_rng(0))


def test_millivolt_scaling(ideal):
    assert ideal.volts(0) == 0.0
    assert ideal.volts(10_000) == pytest.approx(10.0)
    assert ideal.volts(2000) == pytest.approx(2.0, abs=10.0 / 4095)


def test_clipping(ideal):
    assert ideal.volts(-5000) == 0.0
    assert ideal.volts(32_767) == ideal.volts(10_000)
    assert ideal.clip_raw(12_345) == 10_000


def test_dac_resolution(ideal):
    levels = {ideal.volts(mv) for mv in range(5000, 5010)}
    assert 2 <= len(levels) <= 5
    steps = np.diff(sorted(levels))
    assert np.allclose(steps, 10.0 / 4095)


def test_error_value_is_safe_state(rig_config):
    ch = AnalogOutputChannel(rig_config.analog_output, np.random.default_rng(1))
    assert ch.error_volts() == 0.0


def test_module_errors_are_small_and_seeded(rig_config):
    a = AnalogOutputChannel(rig_config.analog_output, np.random.default_rng(2))
    b = AnalogOutputChannel(rig_config.analog_output, np.random.default_rng(2))
    c = AnalogOutputChannel(rig_config.analog_output, np.random.default_rng(3))
    assert a.volts(5000) == b.volts(5000) != c.volts(5000)
    assert abs(a.volts(5000) - 5.0) < 0.03
