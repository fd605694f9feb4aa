"""Pre-drawn noise: the stream's values do not depend on its block size or on how it is read."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plant_emulators.fertilizer.noise import NormalStream, ou_coefficients, spawn


@pytest.mark.parametrize("block", [1, 3, 1024])
def test_stream_hands_out_the_generators_normals_in_order(block):
    stream = NormalStream(np.random.default_rng(5), block=block)
    values = [stream.next() for _ in range(2500)]          # crosses block boundaries
    expected: list[float] = []
    rng = np.random.default_rng(5)
    while len(expected) < len(values):
        expected += rng.standard_normal(block).tolist()
    assert values == expected[:len(values)]
    assert all(type(v) is float for v in values)


def test_stream_draws_a_block_only_when_the_previous_one_is_used_up():
    rng = np.random.default_rng(8)
    stream = NormalStream(rng, block=4)
    first = stream.next()
    state = rng.bit_generator.state
    for _ in range(3):
        stream.next()
    assert rng.bit_generator.state == state                 # still the first block
    stream.next()
    assert rng.bit_generator.state != state
    assert first == np.random.default_rng(8).standard_normal(4)[0]


def test_stream_rejects_an_empty_block():
    with pytest.raises(ValueError, match="block"):
        NormalStream(np.random.default_rng(1), block=0)


def test_spawned_generators_are_independent_of_later_draws_of_the_parent():
    parent = np.random.default_rng(3)
    child = spawn(parent)
    parent.standard_normal(100)
    again = spawn(np.random.default_rng(3))
    assert child.standard_normal(5).tolist() == again.standard_normal(5).tolist()


def test_ou_coefficients_keep_the_stationary_variance():
    a, b = ou_coefficients(0.005, 3.0, 0.02)
    assert a == pytest.approx(math.exp(-0.005 / 3.0))
    assert b * b / (1.0 - a * a) == pytest.approx(0.02 ** 2)
