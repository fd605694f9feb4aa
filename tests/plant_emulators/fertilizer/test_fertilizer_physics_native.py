"""The C twin of the fertilizer plant's step loop gives the Python loop's floats, bit for bit.

Both engines run the same input history (commands, stalls, call partitions) from the same
seed; every output the plant exposes is compared with ``==``. The cases reach every branch of
the loop: the ramp both ways, the PI range, the current and voltage limits in both directions,
I²t derating and its recovery, stick-slip at standstill, a jammed shaft, the power law and the
linear part of the flow map, flute changes, the hopper's starvation and an empty hopper, the
transport delay lines wrapping, and 1 to 48 rows.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.errors import ConfigError
from plant_emulators.engine import ENV_VAR
from plant_emulators.fertilizer.config import FertilizerRigConfig, load_rig_config
from plant_emulators.fertilizer.physics import FertilizerPlant

pytest.importorskip("plant_emulators.fertilizer._plant_native",
                    reason="the C twin is not built (scripts/setup.sh builds it)")

DT = 0.001


def _config(rows: int = 4, motor: dict[str, float] | None = None, **fertilizer: float
            ) -> FertilizerRigConfig:
    overrides: dict[str, dict[str, object]] = {}
    if motor:
        overrides["motor"] = motor
    if rows != 4:
        overrides["meter"] = {"rows": rows}
        overrides["wiring"] = {"flow_module_node_ids": list(range(33, 33 + rows))}
    if fertilizer:
        overrides["fertilizer"] = dict(fertilizer)
    return load_rig_config(overrides=overrides or None)


def _observe(p: FertilizerPlant) -> tuple[object, ...]:
    """Everything the plant exposes after a call (signals() covers the per-row sums)."""
    return (p.time_s, p.motor_speed_rpm, p.shaft_speed_rpm, p.speed_reference_rpm,
            p.motor_current_a, p.motor_voltage_v, p.drive_derated, p.shaft_revolutions,
            p.hopper_kg, p.density_factor, p.flow_at_meter_gps, p.flow_at_sensor_gps,
            p.sensor_passed_g, p.delivered_g, p.metered_g, p.in_transit_g,
            tuple(p.signals().items()))


def _run(engine: str, cfg: FertilizerRigConfig, seed: int, script: list[tuple[int, float, bool]]
         ) -> list[tuple[object, ...]]:
    plant = FertilizerPlant(cfg, np.random.default_rng(seed), engine=engine)
    assert plant.engine == engine
    seen = [_observe(plant)]
    for n, command, stalled in script:
        plant.command_v = command
        plant.stalled = stalled
        plant.advance(n, DT)
        seen.append(_observe(plant))
    return seen


def _script(seed: int, calls: int, *, max_n: int = 40, stall_every: int = 0
            ) -> list[tuple[int, float, bool]]:
    """Random commands (0-10 V, with holds, steps to zero and full scale), random call sizes
    (0 included), optional stalls."""
    rng = np.random.default_rng(seed)
    out = []
    command = 0.0
    for i in range(calls):
        if i % 7 == 0:
            command = float(rng.choice([0.0, 0.2, 10.0, rng.uniform(0.0, 10.0)]))
        stalled = bool(stall_every) and (i // stall_every) % 5 == 4
        out.append((int(rng.integers(0, max_n + 1)), command, stalled))
    return out


def _assert_same(cfg: FertilizerRigConfig, seed: int, script: list[tuple[int, float, bool]]
                 ) -> None:
    python = _run("python", cfg, seed, script)
    native = _run("native", cfg, seed, script)
    assert len(python) == len(native)
    for i, (a, b) in enumerate(zip(python, native, strict=True)):
        assert a == b, f"call {i}: the engines differ"


@pytest.mark.parametrize("seed", [0, 1, 7, 1234])
def test_twin_matches_python_on_random_commands(seed: int) -> None:
    _assert_same(_config(), seed, _script(seed, 600, stall_every=40))


@pytest.mark.parametrize("rows", [1, 12, 48])
def test_twin_matches_python_for_any_row_count(rows: int) -> None:
    _assert_same(_config(rows), rows, _script(rows, 200))


def test_twin_matches_python_on_the_drive_limits() -> None:
    """A 12 V supply (the back-EMF limit binds above ~1,700 rpm), a ramp 50 times steeper and
    a weak current limit: the current sits on the voltage limit, on both current limits and
    in the PI range. (Two branches the plant cannot reach are not exercised, in either
    engine: the lower voltage limit needs the shaft spun backwards at speed, and a shaft
    behind its reference on the upper limit needs an integrator wound past the limit.)"""
    cfg = _config(motor={"supply_v": 12.0, "setpoint_ramp_rpm_per_s": 1.0e6,
                         "current_limit_a": 3.0, "continuous_current_a": 2.0})
    script = _script(11, 500, max_n=60, stall_every=30)
    _assert_same(cfg, 11, script)
    seen = _run("python", cfg, 11, script)
    currents = {obs[4] for obs in seen}
    assert {3.0, -3.0, 2.0} <= currents, "both current limits and the derated limit"
    # on the voltage limit the terminal voltage is the supply, with a current below both limits
    assert any(abs(obs[5] - 12.0) < 1e-3 and 0.0 < obs[4] < 3.0 for obs in seen), "voltage limit"


def test_twin_matches_python_through_starvation_and_an_empty_hopper() -> None:
    # 0.3 kg at full speed: the level falls through the starvation knee and the box runs dry
    cfg = _config(hopper_initial_kg=0.3)
    script = [(25, 10.0, False)] * 800
    _assert_same(cfg, 3, script)
    plant = FertilizerPlant(cfg, np.random.default_rng(3), engine="native")
    for n, command, stalled in script:
        plant.command_v, plant.stalled = command, stalled
        plant.advance(n, DT)
    assert plant.hopper_kg < 0.3 * 0.03 and sum(plant.flow_at_meter_gps) < 1.0


def test_twin_matches_python_through_i2t_derating() -> None:
    """A stall at full command holds the current at the limit until the drive derates, then
    the shaft is freed (the derated drive recovers its budget)."""
    script = [(50, 10.0, True)] * 200 + [(50, 10.0, False)] * 100 + [(50, 0.0, False)] * 100
    python = _run("python", _config(), 5, script)
    assert any(obs[6] for obs in python), "the script must reach the derated state"
    assert python == _run("native", _config(), 5, script)


def test_split_calls_equal_one_call_in_the_twin() -> None:
    """advance(n) equals n x advance(1) in the twin too (the runner relies on it)."""
    one = FertilizerPlant(_config(), np.random.default_rng(9), engine="native")
    many = FertilizerPlant(_config(), np.random.default_rng(9), engine="native")
    one.command_v = many.command_v = 4.0
    one.advance(3000, DT)
    for _ in range(3000):
        many.advance(1, DT)
    assert _observe(one) == _observe(many)


def test_engine_comes_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_VAR, "python")
    assert FertilizerPlant(_config(), np.random.default_rng(0)).engine == "python"
    monkeypatch.delenv(ENV_VAR)
    assert FertilizerPlant(_config(), np.random.default_rng(0)).engine == "native"
    monkeypatch.setenv(ENV_VAR, "fortran")
    with pytest.raises(ConfigError, match="AGRIHIL_PHYSICS='fortran'"):
        FertilizerPlant(_config(), np.random.default_rng(0))
    with pytest.raises(ValueError, match="engine must be one of"):
        FertilizerPlant(_config(), np.random.default_rng(0), engine="fast")


def test_twin_keeps_the_step_checks() -> None:
    plant = FertilizerPlant(_config(), np.random.default_rng(0), engine="native")
    with pytest.raises(ValueError, match="dt must be in"):
        plant.advance(1, 0.01)
    plant.advance(1, DT)
    with pytest.raises(ValueError, match="dt changed"):
        plant.advance(1, 0.002)
    with pytest.raises(ValueError, match="n must be >= 0"):
        plant.advance(-1, DT)
    assert math.isfinite(plant.motor_speed_rpm)


def test_engine_module_examples_run() -> None:
    import doctest

    import plant_emulators.engine as engine_module

    result = doctest.testmod(engine_module)
    assert result.attempted > 0 and result.failed == 0


def test_a_missing_twin_says_how_to_build_it_or_choose_python() -> None:
    from plant_emulators.engine import load_native

    with pytest.raises(ImportError, match=r"scripts/setup\.sh.*AGRIHIL_PHYSICS=python"):
        load_native("plant_emulators.fertilizer._no_such_twin")
