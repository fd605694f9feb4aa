"""The fuzzy self-tuning PID of [D] (eq. 10, Table 2) against the contract (section 2)."""

from __future__ import annotations

import itertools
import random
import time

import pytest

from reference_controllers.sowing_depth.fuzzy import (
    DELTA_KD,
    DELTA_KI,
    DELTA_KP,
    GRID,
    NB,
    NM,
    NS,
    PB,
    PM,
    PS,
    TABLES,
    ZE,
    active_sets,
    centroid,
    fuzzy_gains,
    input_membership,
    output_membership,
)
from reference_controllers.sowing_depth.fuzzy_pid import FuzzyPid, FuzzyPidParams


def literal_fuzzy(e: float, ec: float) -> tuple[float, ...]:
    """The contract's definition with no shortcut: 49 rules, 61 points, 7 sets each."""
    out = []
    for table in TABLES:
        mu = [0.0] * 61
        for i, k in itertools.product(range(7), range(7)):
            w = min(input_membership(e, i), input_membership(ec, k))
            for j, x in enumerate(GRID):
                mu[j] = max(mu[j], min(w, output_membership(x, table[i][k])))
        den = sum(mu)
        out.append(sum(x * m for x, m in zip(GRID, mu, strict=True)) / den if den else 0.0)
    return tuple(out)


def test_rule_tables_cells_as_in_the_contract() -> None:
    assert DELTA_KP[0] == (PB, PB, PM, PM, PS, ZE, ZE)
    assert DELTA_KP[6] == (ZE, ZE, NM, NM, NM, NB, NB)
    assert DELTA_KI[3] == (NM, NM, NS, ZE, PS, PM, PM)
    assert DELTA_KI[4] == (NM, NS, ZE, PS, PS, PM, PB)
    assert DELTA_KD[0] == (PS, NS, NB, NB, NB, NM, PS)
    assert DELTA_KD[4] == (ZE,) * 7
    assert DELTA_KD[5] == (PB, NS, PS, PS, PS, PS, PB)
    assert all(len(t) == 7 and all(len(row) == 7 for row in t) for t in TABLES)


@pytest.mark.parametrize(("x", "label", "mu"), [
    (-6.0, NB, 1.0), (-5.0, NB, 0.5), (-5.0, NM, 0.5), (1.0, ZE, 0.5), (1.0, PS, 0.5),
    (0.0, ZE, 1.0), (0.5, PS, 0.25), (6.0, PB, 1.0), (9.0, PB, 1.0), (-9.0, NM, 0.0),
    (3.0, PS, 0.5), (3.0, PB, 0.0)])
def test_input_memberships(x: float, label: int, mu: float) -> None:
    assert input_membership(x, label) == pytest.approx(mu, abs=1e-15)


def test_active_sets_are_the_sets_with_positive_membership() -> None:
    rng = random.Random(7)
    xs = [rng.uniform(-8, 8) for _ in range(2000)] + [v / 2 for v in range(-16, 17)]
    for x in xs:
        fast = dict(active_sets(x))
        literal = {k: input_membership(x, k) for k in range(7) if input_membership(x, k) > 0}
        assert fast.keys() == literal.keys(), x
        for k in fast:
            assert fast[k] == pytest.approx(literal[k], abs=1e-15)


def test_centroid_known_values() -> None:
    # PB clipped at 1: points 2.1 … 3.0 with μ 0.1 … 1.0: Σxμ / Σμ = 14.85 / 5.5
    assert centroid({PB: 1.0}) == pytest.approx(2.7, abs=1e-12)
    assert centroid({NB: 1.0}) == pytest.approx(-2.7, abs=1e-12)
    assert centroid({ZE: 1.0}) == pytest.approx(0.0, abs=1e-12)
    assert centroid({NS: 0.4}) == pytest.approx(-1.0, abs=1e-12)     # clipped, still symmetric
    assert centroid({}) == 0.0
    # mirror images
    assert centroid({NM: 0.3, NS: 0.7}) == pytest.approx(-centroid({PM: 0.3, PS: 0.7}),
                                                         abs=1e-12)
    # two adjacent sets at the same weight: the plateau between them is symmetric about -1.5
    assert centroid({NM: 1.0, NS: 1.0}) == pytest.approx(-1.5, abs=1e-12)


def test_zero_error_zero_change() -> None:
    up, ui, ud = fuzzy_gains(0.0, 0.0)              # only ZE x ZE fires
    assert up == pytest.approx(0.0, abs=1e-12)      # ΔKp[ZE][ZE] = ZE
    assert ui == pytest.approx(0.0, abs=1e-12)      # ΔKi[ZE][ZE] = ZE
    assert ud == pytest.approx(-1.0, abs=1e-12)     # ΔKd[ZE][ZE] = NS (the classic table)


def test_fast_inference_equals_the_literal_definition() -> None:
    rng = random.Random(11)
    points = [(rng.uniform(-7, 7), rng.uniform(-7, 7)) for _ in range(300)]
    points += [(a, b) for a in (-6, -5, -1, 0, 0.3, 2, 6) for b in (-6, -3, 0, 1, 6)]
    for e, ec in points:
        assert fuzzy_gains(e, ec) == pytest.approx(literal_fuzzy(e, ec), abs=1e-12), (e, ec)


def test_single_rule_symmetry() -> None:
    # E = PB, EC = PB fires one rule: ΔKp NB, ΔKi PB, ΔKd PB; E = NB, EC = NB mirrors Kp, Ki
    up, ui, ud = fuzzy_gains(6.0, 6.0)
    assert (up, ui, ud) == pytest.approx((-2.7, 2.7, 2.7), abs=1e-12)
    up, ui, ud = fuzzy_gains(-6.0, -6.0)
    assert (up, ui) == pytest.approx((2.7, -2.7), abs=1e-12)
    assert ud == pytest.approx(1.0, abs=1e-12)                      # ΔKd[NB][NB] = PS


P = FuzzyPidParams(kp0=2.0, ki0=1.0, kd0=0.2)


def test_reset_when_not_valid_or_not_enabled() -> None:
    pid = FuzzyPid(P)
    pid.step(30.0, 20.0, True, True)
    assert pid.integral != 0.0
    assert pid.step(30.0, 20.0, False, True) == (0.0, 2.0, 1.0, 0.2)
    assert pid.integral == 0.0 and pid.e_prev is None
    assert pid.step(30.0, 20.0, True, False) == (0.0, 2.0, 1.0, 0.2)


def test_one_step_by_hand() -> None:
    pid = FuzzyPid(P)
    speed, kp, ki, kd = pid.step(30.0, 20.0, True, True)   # e = 10, ec = 0 (first step)
    up, ui, ud = fuzzy_gains(0.3, 0.0)
    assert kp == pytest.approx(max(0.0, 2.0 + 0.3 * up), abs=1e-15)
    assert ki == pytest.approx(max(0.0, 1.0 + 0.02 * ui), abs=1e-15)
    assert kd == pytest.approx(max(0.0, 0.2 + 0.5 * ud), abs=1e-15)
    assert speed == pytest.approx(kp * 10.0, abs=1e-12)    # I = 0 before this step, ec = 0
    assert pid.integral == pytest.approx(10.0 * 0.01)
    speed, kp, ki, kd = pid.step(30.0, 21.0, True, True)   # e = 9, ec = -100 mm/s
    up, ui, ud = fuzzy_gains(0.27, -6.0)                   # EC clamped
    kp_, ki_, kd_ = (max(0.0, 2.0 + 0.3 * up), max(0.0, 1.0 + 0.02 * ui),
                     max(0.0, 0.2 + 0.5 * ud))
    assert (kp, ki, kd) == pytest.approx((kp_, ki_, kd_), abs=1e-15)
    assert speed == pytest.approx(max(-50.0, kp_ * 9 + ki_ * 0.1 + kd_ * -100.0), abs=1e-12)


def test_saturation_stops_integration_only_towards_the_error() -> None:
    pid = FuzzyPid(P)
    speed, *_ = pid.step(200.0, 20.0, True, True)          # e = 180: u ≈ 360 > 50
    assert speed == 50.0 and pid.integral == 0.0           # not integrated
    pid = FuzzyPid(P)
    pid.step(30.0, 29.0, True, True)
    pid.integral = -1000.0                                 # u far below -50 with e > 0
    speed, *_ = pid.step(30.0, 29.0, True, True)
    assert speed == -50.0
    assert pid.integral == pytest.approx(-1000.0 + 0.01)   # integrates: it helps


def test_gain_floors() -> None:
    pid = FuzzyPid(FuzzyPidParams(kp0=0.0, ki0=0.0, kd0=0.0))
    _, kp, ki, kd = pid.step(30.0, 30.0, True, True)       # ΔKd NS: 0 - 0.5 → floored
    assert kd == 0.0
    _, kp, ki, kd = pid.step(200.0, 0.0, True, True)       # E = PB, EC = PB: ΔKp NB
    assert kp == 0.0 and ki > 0.0
    pid = FuzzyPid(FuzzyPidParams(kp0=0.0, ki0=0.0, kd0=0.0))
    pid.step(30.0, 30.0, True, True)
    _, kp, ki, kd = pid.step(0.0, 200.0, True, True)       # E = NB, EC = NB: ΔKi NB
    assert ki == 0.0 and kp > 0.0


def test_speed_in_pure_python() -> None:
    pid = FuzzyPid(FuzzyPidParams())
    rng = random.Random(3)
    depths = [30.0 + rng.gauss(0.0, 2.0) for _ in range(5000)]
    start = time.perf_counter()
    for d in depths:
        pid.step(30.0, d, True, True)
    per_step_us = (time.perf_counter() - start) / len(depths) * 1e6
    print(f"\nfuzzy PID core: {per_step_us:.1f} µs/step")
    assert per_step_us < 500.0          # ~30 µs on the development VM; generous for CI
