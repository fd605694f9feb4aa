"""The C twin of the fertilizer plant's step loop gives the Python loop's floats, bit for bit.

Both engines run the same input history (commands, stalls, call partitions) from the same
seed; every output the plant exposes is compared with ``==``. The cases reach every branch of
the loop: the ramp both ways, the PI range, the current and voltage limits in both directions,
I²t derating and its recovery, stick-slip at standstill, a jammed shaft, the power law and the
linear part of the flow map, flute changes, the hopper's starvation and an empty hopper, the
transport delay lines wrapping, and 1 to 48 rows.
"""

from __future__ import annotations

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


def _run(engine: str, cfg: FertilizerRigConfig, seed: int, script: list[tuple[int, float, bool]],
         dt: float = DT) -> list[tuple[object, ...]]:
    plant = FertilizerPlant(cfg, np.random.default_rng(seed), engine=engine)
    assert plant.engine == engine
    seen = [_observe(plant)]
    for n, command, stalled in script:
        plant.command_v = command
        plant.stalled = stalled
        plant.advance(n, dt)
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


def _assert_same(cfg: FertilizerRigConfig, seed: int, script: list[tuple[int, float, bool]],
                 dt: float = DT) -> None:
    """Same observations, compared by ``repr``: exact for floats (it round-trips), and it
    tells -0.0 from 0.0 and True from 1, which ``==`` does not."""
    python = _run("python", cfg, seed, script, dt)
    native = _run("native", cfg, seed, script, dt)
    assert len(python) == len(native)
    for i, (a, b) in enumerate(zip(python, native, strict=True)):
        assert repr(a) == repr(b), f"call {i}: the engines differ"


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


@pytest.mark.parametrize("dt", [0.0005, 0.002, 0.005])
def test_twin_matches_python_at_other_steps_and_long_calls(dt: float) -> None:
    """Other step sizes (other delay lengths and slow-update periods) and calls far longer
    than the delay to the sensor (the Python transport then runs in several chunks)."""
    _assert_same(_config(), 21, _script(21, 60, max_n=700), dt)


def test_twin_matches_python_without_dispersion() -> None:
    cfg = load_rig_config(overrides={"transport": {"dispersion_time_s": 0.0}})
    _assert_same(cfg, 4, _script(4, 120, max_n=300))


def test_twin_follows_a_density_offset_changed_mid_run() -> None:
    """The Python loop reads density_offset_frac on every call; so does the twin."""
    plants = {e: FertilizerPlant(_config(), np.random.default_rng(8), engine=e)
              for e in ("python", "native")}
    for plant in plants.values():
        plant.command_v = 3.0
        plant.advance(500, DT)
        plant.density_offset_frac = -0.2
        plant.advance(500, DT)
    assert repr(_observe(plants["python"])) == repr(_observe(plants["native"]))


def test_a_failed_noise_draw_stops_the_twin_for_good() -> None:
    """The noise source raising mid-step (Ctrl-C inside numpy, say) raises that error; the
    half-stepped twin then refuses to go on instead of stepping from a state the Python model
    could never be in."""
    from plant_emulators.fertilizer._plant_native import NORMAL_BLOCK, PlantCore

    calls = {"n": 0}

    def draw() -> np.ndarray:
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return np.zeros(NORMAL_BLOCK)

    plant = FertilizerPlant(_config(), np.random.default_rng(0), engine="native")
    core = PlantCore(4, 0.02, 1.0, (1.0,) * 4, (0.1, 0.2, 0.3, 0.4), (1.0,) * 4, (0.0,) * 4,
                     50_000.0, 0.0, draw)
    core.bind(DT, plant._drive_constants(DT), plant._meter_constants(DT), 0.5, 80, 400)
    with pytest.raises(KeyboardInterrupt):
        core.advance(20_000, 0.0, False, 1.0)        # ~2,000 slow updates: a second block
    with pytest.raises(RuntimeError, match="earlier draw of noise failed"):
        core.advance(1, 0.0, False, 1.0)
    assert calls["n"] == 2, "the failed source is not asked again"
    with pytest.raises(ValueError, match="must return 1024 C doubles"):
        PlantCore(4, 0.02, 1.0, (1.0,) * 4, (0.1,) * 4, (1.0,) * 4, (0.0,) * 4, 1.0, 0.0,
                  lambda: np.zeros(3))


def test_twin_refuses_delay_lines_that_overflow() -> None:
    from plant_emulators.fertilizer._plant_native import NORMAL_BLOCK, PlantCore

    plant = FertilizerPlant(_config(), np.random.default_rng(0), engine="native")
    core = PlantCore(4, 0.02, 1.0, (1.0,) * 4, (0.1,) * 4, (1.0,) * 4, (0.0,) * 4, 1.0, 0.0,
                     lambda: np.zeros(NORMAL_BLOCK))
    with pytest.raises(MemoryError, match="delay lines"):
        core.bind(DT, plant._drive_constants(DT), plant._meter_constants(DT), 0.5,
                  857988096451607168, 3753697921975781376)
    with pytest.raises(ValueError, match="delays must be >= 1"):
        core.bind(DT, plant._drive_constants(DT), plant._meter_constants(DT), 0.5, 0, 5)


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


def test_engine_module_examples_run() -> None:
    import doctest

    import plant_emulators.engine as engine_module

    result = doctest.testmod(engine_module)
    assert result.attempted > 0 and result.failed == 0


def test_a_missing_twin_says_how_to_build_it_or_choose_python() -> None:
    from plant_emulators.engine import load_native

    with pytest.raises(ImportError, match=r"scripts/setup\.sh.*AGRIHIL_PHYSICS=python"):
        load_native("plant_emulators.fertilizer._no_such_twin")
