"""The C twin of the ground-speed step loop gives the Python loop's floats, bit for bit.

Both engines run the same target history (standstill, ramps, stops, 0.5-4 m/s) with the same
random call partitions (0 to 40 steps) from the same seed; everything the model exposes (every
public attribute, the Hall node's report, the tractor reports, the signals) is compared with
``==`` after every call. The cases reach every branch of the loop: the acceleration limit both
ways, a negative speed clamped to zero (a wild speed variation), negative slips and a ground
wheel turning backwards, several Hall edges in one step, one magnet per revolution, the edge
history wrapping, step sizes from 0.5 to 5 ms, and every branch of the Hall report (no edge,
one edge, timed out, steady, slowing down).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hil.errors import ConfigError
from plant_emulators.engine import ENV_VAR
from plant_emulators.fertilizer.config import GroundSpeedConfig, load_rig_config
from plant_emulators.fertilizer.ground_speed import GroundSpeedModel, HallReport

native = pytest.importorskip("plant_emulators.fertilizer._ground_speed_native",
                             reason="the C twin is not built (scripts/setup.sh builds it)")

DT = 0.001


@pytest.fixture(scope="module")
def config() -> GroundSpeedConfig:
    return load_rig_config().ground_speed


def _observe(m: GroundSpeedModel) -> tuple[object, ...]:
    """Everything the model exposes after a call: every public attribute (with its type: the
    pulse count stays an int), the reports and the signals."""
    public = sorted((k, type(v), v) for k, v in vars(m).items()
                    if not k.startswith("_") and k != "engine")
    return (tuple(public), m.time_s, m.hall_pulses, m.hall_report(), m.wheel_based_report(),
            m.ground_based_report(), tuple(m.signals().items()))


def _script(seed: int, calls: int, *, max_n: int = 40, top_mps: float = 4.0
            ) -> list[tuple[int, float]]:
    """Random call sizes (0 included) and targets: holds at 0.5-4 m/s, ramps up and down,
    steps to zero (the wheel stops and the Hall node times out)."""
    rng = np.random.default_rng(seed)
    out: list[tuple[int, float]] = []
    target = 0.0
    ramp = 0.0
    for i in range(calls):
        if i % 50 == 0:
            kind = int(rng.integers(0, 4))
            if kind == 0:
                target, ramp = 0.0, 0.0
            elif kind == 1:
                target, ramp = float(rng.uniform(0.5, top_mps)), 0.0
            else:
                ramp = float(rng.uniform(0.001, 0.05)) * (1 if kind == 2 else -1)
        target = min(max(target + ramp, 0.0), top_mps)
        out.append((int(rng.integers(0, max_n + 1)), target))
    return out


def _run(engine: str, cfg: GroundSpeedConfig, seed: int, script: list[tuple[int, float]],
         dt: float = DT) -> list[tuple[object, ...]]:
    model = GroundSpeedModel(cfg, np.random.default_rng(seed), engine=engine)
    assert model.engine == engine
    seen = [_observe(model)]
    for n, target in script:
        model.target_speed_mps = target
        model.advance(n, dt)
        seen.append(_observe(model))
    return seen


def _assert_same(cfg: GroundSpeedConfig, seed: int, script: list[tuple[int, float]],
                 dt: float = DT) -> list[tuple[object, ...]]:
    python = _run("python", cfg, seed, script, dt)
    twin = _run("native", cfg, seed, script, dt)
    assert len(python) == len(twin)
    for i, (a, b) in enumerate(zip(python, twin, strict=True)):
        # repr: exact for floats, and it tells -0.0 from 0.0 and True from 1 (== does not)
        assert repr(a) == repr(b), f"call {i}: the engines differ"
    return python


def _python_state(m: GroundSpeedModel) -> tuple[object, ...]:
    """The Python model's state in the order of the twin's state()."""
    return (m._v, m._dist, m._wheel_dist, m._wb_dist, m._gb_dist, m._variation,
            m._wheel_slip, m._tractor_slip, m._radar_noise, m._vib[0], m._vib[1],
            m._pulse_pos, m._next_edge, m._pulses, m._steps, m._countdown)


@pytest.mark.parametrize("seed", [0, 1, 7, 1234])
def test_twin_matches_python_on_random_targets_and_partitions(config, seed: int) -> None:
    seen = _assert_same(config, seed, _script(seed, 1500))
    reports = [obs[3] for obs in seen]
    assert any(r.moving for r in reports) and any(not r.moving for r in reports[1:])


@pytest.mark.parametrize("dt", [0.0005, 0.0007, 0.003, 0.005])
def test_twin_matches_python_for_other_step_sizes(config, dt: float) -> None:
    _assert_same(config, 21, _script(21, 600), dt)


def test_twin_matches_python_on_a_field_run(config) -> None:
    """The rig's pattern: advance(10) at 6 km/h for 30 s, then a stop; the internal state
    (what is not observable yet, like the next edge's position) is the same too, and so are
    the recorded edges (the history wraps: thousands of pulses)."""
    python = GroundSpeedModel(config, np.random.default_rng(42), engine="python")
    twin = GroundSpeedModel(config, np.random.default_rng(42), engine="native")
    for i in range(3500):
        target = 6 / 3.6 if i < 3000 else 0.0
        for m in (python, twin):
            m.target_speed_mps = target
            m.advance(10, DT)
        assert _observe(python) == _observe(twin), f"call {i}"
    assert python.hall_pulses > 2 * native.EDGE_HISTORY
    assert _python_state(python) == twin._core.state()
    assert tuple(python._edges) == twin._core.edges()
    assert len(twin._core.edges()) == native.EDGE_HISTORY


def test_twin_matches_python_on_wild_processes(config) -> None:
    """Speed variation large enough to ask for a negative speed (clamped at zero), slips
    that go negative and beyond 1 (a ground wheel turning backwards), large magnet errors."""
    cfg = dataclasses.replace(config, speed_variation_sd_frac=1.5, speed_variation_time_s=0.05,
                              wheel_slip_sd_frac=0.8, wheel_slip_time_s=0.05,
                              tractor_slip_sd_frac=0.3, radar_noise_sd_frac=0.5,
                              pulse_spacing_error_sd_frac=0.19)
    script = _script(5, 1500)
    _assert_same(cfg, 5, script)
    model = GroundSpeedModel(cfg, np.random.default_rng(5), engine="python")
    clamped = backwards = False
    for n, target in script:
        model.target_speed_mps = target
        model.advance(n, DT)
        clamped |= model.true_speed_mps == 0.0 and target > 0.0
        backwards |= model._wheel_slip > 1.0
    assert clamped and backwards


@pytest.mark.parametrize("pulses_per_rev", [1, 2, 3000])
def test_twin_matches_python_for_any_magnet_count(config, pulses_per_rev: int) -> None:
    """One magnet (every edge uses the same error), and 3,000 on a small wheel at 4 m/s:
    several edges per step."""
    cfg = dataclasses.replace(config, pulses_per_rev=pulses_per_rev,
                              wheel_diameter_m=0.3 if pulses_per_rev > 100 else 0.52)
    seen = _assert_same(cfg, pulses_per_rev, _script(pulses_per_rev, 600))
    if pulses_per_rev > 100:
        model = GroundSpeedModel(cfg, np.random.default_rng(1), engine="native")
        model.target_speed_mps = 4.0
        model.advance(20_000, DT)
        before = model.hall_pulses
        model.advance(1, DT)
        assert model.hall_pulses - before >= 2
    assert seen[-1][2] > 0


def test_hall_report_branches_match(config) -> None:
    """No edge yet, a single edge, the first periods, steady, slowing, timed out."""
    python = GroundSpeedModel(config, np.random.default_rng(8), engine="python")
    twin = GroundSpeedModel(config, np.random.default_rng(8), engine="native")
    assert python.hall_report() == twin.hall_report() == HallReport(0.0, 0, 0.0, False)
    assert type(twin.hall_report()) is HallReport
    kinds = set()
    for i in range(12_000):
        target = 1.0 if i < 3000 else 0.0
        for m in (python, twin):
            m.target_speed_mps = target
            m.advance(1, DT)
        a, b = python.hall_report(), twin.hall_report()
        assert a == b, f"step {i}"
        kinds.add((a.pulse_count, a.moving, a.last_period_s > 0.0) if a.pulse_count < 2
                  else (2, a.moving))
        if a.moving and a.wheel_speed_mps == config.reported_metres_per_pulse / (
                python.time_s - python._edges[-1]):
            kinds.add("slowing")      # the time since the last edge bounds the speed
    assert {(1, False, False), (2, True), (2, False), "slowing"} <= kinds


def test_odd_targets_are_read_as_the_python_model_reads_them(config) -> None:
    """Negative, integer and numpy targets: max(0.0, float(target)) on both sides."""
    script = [(30, -1.0), (30, 2), (30, np.float64(1.5)), (30, np.float32(0.7)), (30, -0.0)]
    _assert_same(config, 3, script)


def test_engine_comes_from_the_environment(config, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_VAR, "python")
    model = GroundSpeedModel(config, np.random.default_rng(0))
    assert model.engine == "python" and model._core is None
    monkeypatch.delenv(ENV_VAR)
    model = GroundSpeedModel(config, np.random.default_rng(0))
    assert model.engine == "native" and model._core is not None
    monkeypatch.setenv(ENV_VAR, "Native ")
    assert GroundSpeedModel(config, np.random.default_rng(0)).engine == "native"
    monkeypatch.setenv(ENV_VAR, "fortran")
    with pytest.raises(ConfigError, match="AGRIHIL_PHYSICS='fortran'"):
        GroundSpeedModel(config, np.random.default_rng(0))
    monkeypatch.delenv(ENV_VAR)
    with pytest.raises(ValueError, match="engine must be one of"):
        GroundSpeedModel(config, np.random.default_rng(0), engine="fast")


def test_twin_raises_where_the_python_model_divides_by_zero(config) -> None:
    """A magnet error below -1 puts the first edge behind the wheel: at standstill the edge
    time divides by a zero step (ZeroDivisionError in Python; the twin says the same)."""
    errors = (-1.5,) * config.pulses_per_rev
    python = GroundSpeedModel(config, np.random.default_rng(0), engine="python")
    python._pulse_spacing_errors = errors        # a test-only reach inside: read-only API
    python._next_edge = 1.0 + errors[1]
    with pytest.raises(ZeroDivisionError):
        python.advance(1, DT)
    model = GroundSpeedModel(config, np.random.default_rng(0), engine="python")
    core = native.GroundSpeedCore(errors, 0.0, 0.04, 0.08, 0.0, model._ar1, model._ar2,
                                  model._ar_gain, model._radar_gain, 1.5, 1.0, 0.25, 0.05,
                                  HallReport, lambda: np.zeros(native.NORMAL_BLOCK))
    model._bind_dt(DT)
    core.bind(DT, model._k)
    with pytest.raises(ZeroDivisionError):
        core.advance(1, 0.0)


@pytest.mark.parametrize("engine", ["native", "python"])
def test_the_magnet_errors_are_fixed_for_the_run(config, engine: str) -> None:
    """The twin takes them when it is built: they cannot be swapped under either engine."""
    model = GroundSpeedModel(config, np.random.default_rng(0), engine=engine)
    with pytest.raises(AttributeError):
        model.pulse_spacing_errors = (0.0,) * config.pulses_per_rev  # type: ignore[misc]


def test_a_broken_noise_source_is_reported_and_stops_the_twin(config) -> None:
    model = GroundSpeedModel(config, np.random.default_rng(0), engine="python")
    model._bind_dt(DT)
    core = native.GroundSpeedCore(model.pulse_spacing_errors, 0.0, 0.04, 0.08, 0.0, 0.0, 0.0,
                                  1.0, 1.0, 1.5, 1.0, 0.25, 0.05, HallReport,
                                  lambda: np.zeros(3))
    core.bind(DT, model._k)
    with pytest.raises(ValueError, match="1024 C doubles"):
        core.advance(1, 1.0)
    with pytest.raises(RuntimeError, match="earlier draw of noise failed"):
        core.advance(1, 1.0)


def test_the_step_count_cannot_overflow(config) -> None:
    model = GroundSpeedModel(config, np.random.default_rng(0), engine="native")
    model.advance(1, DT)
    with pytest.raises(OverflowError):
        model.advance(2**63 - 1, DT)
    assert model.time_s == DT
