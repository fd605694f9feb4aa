"""The fertilizer plant FMU's variables: names, units, causality, descriptions, start values.

The order is the value references of ``native/fertilizer_plant/config.h`` (checked by
:func:`check_against_header`). Parameters are ``rig.toml``'s physics parameters under their
dotted keys (``motor.supply_v``), the run's draws (``run.row_gain_1`` ...: what the rig draws
from the run's seed when it builds the plant) and ``seed`` (the FMU's own noise generator).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plant_emulators.fertilizer.config import FertilizerRigConfig

HEADER = Path(__file__).parent / "native" / "fertilizer_plant" / "config.h"
ROWS = 4


@dataclass(frozen=True)
class Variable:
    """One scalar variable of the FMU."""

    name: str
    causality: str          # independent, input, output, parameter
    unit: str
    description: str
    start: float | int | None = None
    kind: str = "Real"      # Real or Integer

    @property
    def c_name(self) -> str:
        return "vr_" + self.name.replace(".", "_")


#: rig.toml's parameters the plant reads, by section: (key, unit)
CONFIG_PARAMETERS: dict[str, tuple[tuple[str, str], ...]] = {
    "motor": (("supply_v", "V"), ("ke_v_per_krpm", "V/krpm"), ("armature_resistance_ohm", "Ohm"),
              ("rotor_inertia_kg_cm2", "kg.cm2"), ("load_inertia_at_motor_kg_cm2", "kg.cm2"),
              ("coulomb_friction_nm", "N.m"), ("viscous_friction_nm_per_krpm", "N.m/krpm"),
              ("current_limit_a", "A"), ("continuous_current_a", "A"),
              ("peak_current_time_s", "s"), ("command_full_scale_v", "V"),
              ("speed_at_full_command_rpm", "rpm"), ("command_deadband_v", "V"),
              ("speed_loop_bandwidth_hz", "Hz"), ("speed_loop_damping", "1"),
              ("setpoint_ramp_rpm_per_s", "rpm/s")),
    "drive": (("gear_ratio", "1"), ("chain_ratio", "1"), ("reducer_efficiency", "1"),
              ("shaft_friction_nm", "N.m")),
    "meter": (("flow_coeff_gps", "g/s"), ("flow_exponent", "1"), ("linear_below_rpm", "rpm"),
              ("pulsation_first_harmonic_frac", "1"), ("pulsation_second_harmonic_frac", "1"),
              ("flute_charge_sd_frac", "1"), ("roller_torque_nm", "N.m"),
              ("roller_torque_per_rpm_nm", "N.m/rpm")),
    "fertilizer": (("density_drift_sd_frac", "1"), ("density_drift_time_s", "s"),
                   ("hopper_capacity_kg", "kg"), ("hopper_initial_kg", "kg"),
                   ("level_sensitivity_frac", "1"), ("starvation_fill_frac", "1")),
    "transport": (("meter_to_sensor_delay_s", "s"), ("sensor_to_exit_delay_s", "s"),
                  ("dispersion_time_s", "s")),
}


@dataclass(frozen=True)
class RunDraws:
    """What the rig draws from a run's seed when it builds the plant."""

    row_gain: tuple[float, ...]
    flute_offset: tuple[float, ...]
    density_offset_frac: float
    density_wander: float


def run_draws(config: FertilizerRigConfig, seed: int) -> RunDraws:
    """The plant's draws of a run with ``seed``: the rig builds its plant first from the run's
    generator, so a plant built here from ``default_rng(seed)`` draws the same (the Python
    engine keeps the flute offsets and the wander where they can be read)."""
    from plant_emulators.fertilizer.physics import FertilizerPlant

    plant = FertilizerPlant(config, np.random.default_rng(seed), engine="python")
    return RunDraws(tuple(plant.row_gain), tuple(plant._flute_offsets),
                    plant.density_offset_frac, plant._density_wander)


def variables(config: FertilizerRigConfig, draws: RunDraws, seed: int) -> list[Variable]:
    """Every variable, in value-reference order, with ``config``'s and ``draws``' starts."""
    out = [Variable("time", "independent", "s", "simulation time"),
           Variable("command_v", "input", "V", "voltage at the drive's analog speed input "
                    "(0-10 V: the analog output module's output)", 0.0),
           Variable("motor_speed_rpm", "output", "rpm", "motor speed"),
           Variable("shaft_speed_rpm", "output", "rpm", "meter-shaft speed"),
           Variable("motor_current_a", "output", "A", "motor current"),
           Variable("delivered_total_g", "output", "g", "grams delivered at the tube exits, all "
                    "rows (the truth)"),
           Variable("flow_at_meter_mean_gps", "output", "g/s", "flow leaving the rollers, mean "
                    "of the rows"),
           Variable("metered_total_g", "output", "g", "grams that left the rollers, all rows "
                    "(delivered plus in the tubes: what a scale weighs after the run)")]
    for name, unit, what in (("flow_at_meter_{}_gps", "g/s", "flow leaving roller {}"),
                             ("flow_at_sensor_{}_gps", "g/s", "flow passing row {}'s sensor"),
                             ("delivered_{}_g", "g", "grams delivered at row {}'s tube exit"),
                             ("sensor_passed_{}_g", "g", "grams that passed row {}'s sensor")):
        out += [Variable(name.format(r), "output", unit, what.format(r))
                for r in range(1, ROWS + 1)]
    for section, keys in CONFIG_PARAMETERS.items():
        table = getattr(config, section)
        for key, unit in keys:
            out.append(Variable(f"{section}.{key}", "parameter", unit,
                                f"rig.toml [{section}] {key}", float(getattr(table, key))))
    out += [Variable(f"run.row_gain_{r + 1}", "parameter", "1", f"roller {r + 1}'s delivery "
                     "factor (drawn per run)", draws.row_gain[r]) for r in range(ROWS)]
    out += [Variable(f"run.flute_offset_{r + 1}", "parameter", "1", f"roller {r + 1}'s flute "
                     "phase, in flutes (drawn per run)", draws.flute_offset[r])
            for r in range(ROWS)]
    out += [Variable("run.density_offset_frac", "parameter", "1", "the lot's delivery offset "
                     "against the calibration (drawn per run)", draws.density_offset_frac),
            Variable("run.density_wander", "parameter", "1", "the bulk density wander's start "
                     "(drawn per run)", draws.density_wander),
            Variable("meter.flutes", "parameter", "1", "rig.toml [meter] flutes",
                     int(config.meter.flutes), "Integer"),
            Variable("seed", "parameter", "1", "seed of the FMU's own noise generator (flute "
                     "charges, density wander)", int(seed), "Integer")]
    return out


def check_against_header(vs: list[Variable], header: Path = HEADER) -> None:
    """The header's value references are the list's order (one source each side, checked).

    Raises
    ------
    AssertionError
        A name or position differs (naming the first).
    """
    text = header.read_text()
    body = text[text.index("typedef enum {"):text.index("} ValueReference;")]
    names = [n for n in re.findall(r"\b(vr_\w+)", body)
             if n not in ("vr_first_parameter", "vr_end_of_reals")]
    assert names == [v.c_name for v in vs], next(
        (f"{a} != {b}" for a, b in zip(names, [v.c_name for v in vs], strict=False) if a != b),
        f"{len(names)} names in the header, {len(vs)} variables")


def start_values_header(vs: list[Variable]) -> str:
    """``start_values.h``: the C defaults, equal to the model description's starts (hex
    floats: bit for bit)."""
    reals = [v for v in vs if v.kind == "Real" and v.causality in ("input", "output",
                                                                   "parameter")]
    values = [float(v.start).hex() if v.start is not None else "0.0" for v in reals]
    ints = {v.name: int(v.start or 0) for v in vs if v.kind == "Integer"}
    return ("/* generated by plant_emulators/fmu_export: the start values of the model "
            "description */\n"
            f"#define START_REALS {{{', '.join(values)}}}\n"
            f"#define START_FLUTES {ints['meter.flutes']}\n"
            f"#define START_SEED {ints['seed']}\n")
