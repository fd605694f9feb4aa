"""The C twin of the flow detection module's step loop gives the Python loop's floats, bit for bit.

Both engines run the same input history (call partitions, flows from an empty pipe to far
beyond the AD7746's range, vibration, the stuck/garbage/silent faults, reports taken or left
pending) from the same seed; everything the module exposes is compared with ``==`` after every
call, every float also by its bits, and the twin's whole internal state against the Python
model's attributes. The cases cover both modes, the start-up baseline (with and without flow),
overrange in both directions of the clip, the window ends falling inside calls, at their ends
and in calls of zero steps.
"""

from __future__ import annotations

import dataclasses
import math
import struct

import numpy as np
import pytest

from hil.errors import ConfigError
from plant_emulators.engine import ENV_VAR
from plant_emulators.fertilizer.config import FlowSensorConfig, load_rig_config
from plant_emulators.fertilizer.flow_sensor import FlowSensor, SensorStatus, _crossing

pytest.importorskip("plant_emulators.fertilizer._flow_sensor_native",
                    reason="the C twin is not built (scripts/setup.sh builds it)")

DT = 0.001
_STATE_KEYS = ("steps", "sub_at", "sub_clock", "holdup_g", "inv_tau", "jitter", "drift_pf", "h_acc",
               "conv_start", "t_conv", "baseline_acc", "baseline_n", "baseline_pf",
               "sub_sum_pf", "sub_overrange")


@pytest.fixture(scope="module")
def sensor_config() -> FlowSensorConfig:
    return load_rig_config().flow_sensor


def _bits(value: object) -> object:
    """``value`` with every float replaced by its IEEE bits (so -0.0 != 0.0, NaN == NaN)."""
    if isinstance(value, float):
        return struct.pack("<d", value).hex()
    if isinstance(value, dict):
        return {k: _bits(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_bits(v) for v in value]
    return value


def _observe(s: FlowSensor) -> tuple[object, ...]:
    """Everything the module exposes between calls (reports are taken by the script)."""
    return (s.time_s, s.baseline_ready, s.baseline_pf, s.holdup_g, s.reports_pending,
            s.next_report_time_s(), s.step_s, s.report_period_s, tuple(s.signals().items()))


def _state(s: FlowSensor) -> dict[str, object]:
    """The per-step state: the twin's, or the Python model's attributes under the same names."""
    if s._core is not None:
        return s._core.state()
    return {key: getattr(s, f"_{key}") for key in _STATE_KEYS}


Call = tuple[int, float, float, bool, bool, bool, bool]
"""(n, flow_gps, vibration_rms_mps2, stuck, garbage, silent, take_reports)"""


def _script(seed: int, calls: int, *, max_n: int = 40) -> list[Call]:
    """Random call sizes (0 included); flows held for a few calls: zero (the first ~3 s, for
    the baseline, and later), negative, ordinary, and far beyond the ADC's range; vibration
    changing now and then; faults toggled."""
    rng = np.random.default_rng(seed)
    out: list[Call] = []
    flow = vibration = 0.0
    stuck = garbage = silent = False
    for i in range(calls):
        if i % 9 == 0:
            flow = float(rng.choice([0.0, -5.0, 2.5, rng.uniform(0.0, 60.0),
                                     rng.uniform(0.0, 60.0), 4000.0, 1.0e7]))
        if i % 13 == 0:
            vibration = float(rng.choice([0.0, 2.5, rng.uniform(0.0, 20.0)]))
        if i % 97 == 50:
            stuck = not stuck
        if i % 113 == 80:
            garbage = not garbage
        if i % 71 == 30:
            silent = not silent
        early = i < 3000 // (max_n // 2 + 1)                # empty pipe at start-up
        out.append((int(rng.integers(0, max_n + 1)), 0.0 if early else flow, vibration,
                    stuck, garbage, silent, bool(rng.random() < 0.3)))
    return out


def _run(engine: str, cfg: FlowSensorConfig, seed: int, mode: str, script: list[Call]
         ) -> tuple[list[object], list[object]]:
    sensor = FlowSensor(cfg, np.random.default_rng(seed), mode=mode, engine=engine)
    assert sensor.engine == engine
    assert (sensor._core is not None) == (engine == "native")
    seen: list[object] = [_observe(sensor)]
    states: list[object] = [_state(sensor)]
    for n, flow, vibration, stuck, garbage, silent, take in script:
        sensor.vibration_rms_mps2 = vibration
        sensor.stuck, sensor.garbage, sensor.silent = stuck, garbage, silent
        sensor.advance(n, DT, flow)
        seen.append((_observe(sensor), sensor.take_reports() if take else None))
        states.append(_state(sensor))
    seen.append(sensor.take_reports())
    return seen, states


def _assert_same(cfg: FlowSensorConfig, seed: int, mode: str, script: list[Call]
                 ) -> list[object]:
    python, py_states = _run("python", cfg, seed, mode, script)
    native, nat_states = _run("native", cfg, seed, mode, script)
    assert len(python) == len(native)
    for i, (a, b) in enumerate(zip(python, native, strict=True)):
        assert a == b, f"call {i}: the engines differ"
        assert _bits(a) == _bits(b), f"call {i}: the engines differ in a float's bits"
    for i, (a, b) in enumerate(zip(py_states, nat_states, strict=True)):
        assert _bits(a) == _bits(b), f"call {i}: the engines' states differ"
    return python


def _reports(seen: list[object]) -> list[object]:
    out = []
    for entry in seen[1:-1]:
        reports = entry[1]
        if reports:
            out += reports
    return out + seen[-1]


@pytest.mark.parametrize("mode", ["block", "sliding"])
@pytest.mark.parametrize("seed", [0, 1, 7, 1234])
def test_twin_matches_python_on_random_calls(sensor_config, seed: int, mode: str) -> None:
    seen = _assert_same(sensor_config, seed, mode, _script(seed, 1500))
    reports = _reports(seen)
    assert len(reports) >= (25 if mode == "block" else 250)
    # the script reached what it is meant to cover
    assert any(r.status & SensorStatus.BASELINE_READY for r in reports)
    assert any(r.status & SensorStatus.ADC_OVERRANGE for r in reports)
    assert any(r.flow_gps > sensor_config.flow_valid_max_gps for r in reports)   # garbage
    assert any(0.5 < r.flow_gps < 60.0 for r in reports)


@pytest.mark.parametrize("mode", ["block", "sliding"])
def test_twin_matches_python_with_single_steps_and_long_calls(sensor_config, mode) -> None:
    script: list[Call] = [(1, 0.0, 0.0, False, False, False, True)] * 2500
    script += [(2000, 25.0, 3.0, False, False, False, True), (0, 25.0, 3.0, False, False,
                                                              False, True)]
    script += [(1, 31.0, 3.0, False, False, False, False)] * 1500
    script += [(12_345, 12.5, 0.0, False, False, False, True)]
    _assert_same(sensor_config, 42, mode, script)


def test_twin_matches_python_with_flow_during_the_baseline_and_other_constants(
        sensor_config) -> None:
    """Flow while the baseline is acquired, a short baseline, fast conversions, a tight input
    range (the clip on both sides: a negative drift offset), the intercept applied and a
    clock far off."""
    cfg = dataclasses.replace(sensor_config, baseline_samples=7, conversion_time_ms=2.5,
                              adc_range_pf=1.05, intercept="per_window",
                              baseline_drift_sd_ff=200.0, clock_error_sd_ppm=5000.0,
                              adc_noise_rms_af=3000.0)
    for seed in (3, 4, 5):
        seen = _assert_same(cfg, seed, "sliding", _script(seed + 100, 600, max_n=25))
        assert any(r.status & SensorStatus.ADC_OVERRANGE for r in _reports(seen))


def test_twin_matches_python_without_quantization_hiding_the_rounding(sensor_config) -> None:
    """With the AD7746's LSB (0.488 aF, some 10^9 ulps of a 1 pF reading) a conversion that
    differs in its last bits usually quantizes to the same value, which would hide an
    operation done in another order. An LSB far below an ulp leaves every bit visible."""
    cfg = dataclasses.replace(sensor_config, adc_lsb_af=1e-12, baseline_samples=20)
    for mode in ("block", "sliding"):
        _assert_same(cfg, 21, mode, _script(21, 400))


@pytest.mark.parametrize(("lsb_af", "range_pf"), [(400_000.0, 4.096), (1.0e6, 1.0)])
def test_twin_matches_python_on_exact_ties(sensor_config, lsb_af: float, range_pf: float
                                           ) -> None:
    """A noise-free module reads exactly 1 pF in an empty pipe. With an LSB of 0.4 pF that is
    2.5 LSBs, a tie that round() takes to the even 2; with a 1 pF range it sits exactly on
    the range, which is not overrange (``abs(c) > range``)."""
    cfg = dataclasses.replace(sensor_config, transit_jitter_sd_frac=0.0,
                              baseline_drift_sd_ff=0.0, adc_noise_rms_af=0.0,
                              vibration_noise_ff_per_mps2=0.0, adc_lsb_af=lsb_af,
                              adc_range_pf=range_pf, baseline_samples=5)
    script: list[Call] = [(37, 0.0, 0.0, False, False, False, True)] * 100
    seen = _assert_same(cfg, 2, "sliding", script)
    sensor = FlowSensor(cfg, np.random.default_rng(2), mode="sliding", engine="native")
    sensor.advance(500, DT, 0.0)
    reports = sensor.take_reports()
    if lsb_af == 400_000.0:
        assert sensor.baseline_pf == 2 * (lsb_af * 1e-6)
    else:
        assert sensor.baseline_pf == 1.0
        assert reports[-1].status & SensorStatus.BASELINE_READY
        assert not any(r.status & SensorStatus.ADC_OVERRANGE for r in _reports(seen))


def test_twin_matches_python_for_other_step_sizes(sensor_config) -> None:
    for dt in (0.0005, 0.0011, 0.011):
        runs = []
        for engine in ("python", "native"):
            s = FlowSensor(sensor_config, np.random.default_rng(8), engine=engine)
            s.advance(int(3.0 / dt), dt, 0.0)
            s.advance(int(5.0 / dt) + 3, dt, 22.0)
            runs.append((_observe(s), s.take_reports(), _bits(_state(s))))
        assert runs[0] == runs[1]


def test_a_non_finite_flow_raises_in_both_engines(sensor_config) -> None:
    """An infinite flow makes the holdup NaN; round() of a NaN raises ValueError in Python,
    and the twin raises the same."""
    for engine in ("python", "native"):
        s = FlowSensor(sensor_config, np.random.default_rng(1), engine=engine)
        s.advance(100, DT, 0.0)
        with pytest.raises(ValueError, match="cannot convert float NaN to integer"):
            s.advance(30, DT, math.inf)
        s2 = FlowSensor(sensor_config, np.random.default_rng(1), engine=engine)
        s2.advance(100, DT, math.nan)             # NaN is not > 0: an empty pipe
        assert s2.holdup_g == 0.0


def test_split_calls_equal_one_call_in_the_twin(sensor_config) -> None:
    """advance(n) equals n x advance(1) in the twin too (the runner relies on it)."""
    one = FlowSensor(sensor_config, np.random.default_rng(9), mode="sliding", engine="native")
    many = FlowSensor(sensor_config, np.random.default_rng(9), mode="sliding", engine="native")
    one.advance(3000, DT, 0.0)
    one.advance(4000, DT, 18.0)
    for _ in range(3000):
        many.advance(1, DT, 0.0)
    for _ in range(4000):
        many.advance(1, DT, 18.0)
    assert _observe(one) == _observe(many)
    assert one.take_reports() == many.take_reports()
    assert one._core.state() == many._core.state()


def test_engine_comes_from_the_environment(sensor_config,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_VAR, "python")
    sensor = FlowSensor(sensor_config, np.random.default_rng(0))
    assert sensor.engine == "python" and sensor._core is None
    monkeypatch.setenv(ENV_VAR, "native")
    sensor = FlowSensor(sensor_config, np.random.default_rng(0))
    assert sensor.engine == "native" and sensor._core is not None
    monkeypatch.delenv(ENV_VAR)
    assert FlowSensor(sensor_config, np.random.default_rng(0)).engine == "native"
    monkeypatch.setenv(ENV_VAR, "fortran")
    with pytest.raises(ConfigError, match="AGRIHIL_PHYSICS='fortran'"):
        FlowSensor(sensor_config, np.random.default_rng(0))
    with pytest.raises(ValueError, match="engine must be one of"):
        FlowSensor(sensor_config, np.random.default_rng(0), engine="fast")


def test_twin_core_refuses_misuse() -> None:
    from plant_emulators.fertilizer._flow_sensor_native import FlowSensorCore

    core = FlowSensorCore(0.011, 0.9, 0.1, 0.99, 0.01, 0.02, 1.0, 4.0, 1e-6, 3, 0.0, 0.0, 50.0,
                          lambda: np.zeros(7))
    with pytest.raises(RuntimeError, match="bind first"):
        core.advance(1, 0.0, 0.0)
    core.bind(DT, DT, 0.011, 1.0, 1.0)
    with pytest.raises(RuntimeError, match="bound once"):
        core.bind(DT, DT, 0.011, 1.0, 1.0)
    with pytest.raises(ValueError, match="C doubles"):          # the source gives 7, not 1024
        core.advance(50, 1.0, 0.0)
    from plant_emulators.fertilizer._flow_sensor_native import crossing

    with pytest.raises(ValueError, match="clock does not advance"):
        crossing(1.0, 1e-17, 2.0)                       # _crossing would never return
    for bad in ((0.0, 0.0, 1.0), (0.0, 1e-3, math.nan), (0.0, 1e-3, math.inf)):
        with pytest.raises(ValueError, match="finite"):
            crossing(*bad)


def test_twin_schedules_the_window_ends_as_crossing_does() -> None:
    """The twin's window scheduling is ``_crossing``: the same additions, the same result."""
    from plant_emulators.fertilizer._flow_sensor_native import crossing

    rng = np.random.default_rng(17)
    for _ in range(2000):
        step = float(rng.uniform(1e-4, 1.1e-2)) * (1.0 + float(rng.normal(0.0, 3e-5)))
        due = float(rng.choice([rng.uniform(0.0, 1.2), rng.uniform(0.0, 50.0), 0.0, -1.0]))
        t0 = float(rng.uniform(-step, step))
        assert crossing(t0, step, due) == _crossing(t0, step, due)
    assert crossing(0.0, 0.001, 0.011) == (11, 0.011000000000000003)
