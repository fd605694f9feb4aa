"""The operator's calibration ("rotation") test of a fertilizer lot, from the rig's physics.

Before sowing a new lot the operator turns the meter ``N`` revolutions at a working speed with
the tubes off, weighs what all rows discharged and enters the grams per revolution on the
terminal (``[calibration_test]`` of ``rig.toml`` gives N, the speed and the scale, with their
sources). What the scale reads is the meter's own delivery over those revolutions, as the
plant (:mod:`plant_emulators.fertilizer.physics`) meters it:

* the flow map's grams per revolution at the test speed, ``60·q(n)/n``;
* the lot (``density_offset_mean_frac``) and the state of the product on the day of the test:
  a day offset drawn as each run draws its own (``density_offset_sd_frac``) and the slow
  wander at the test (``density_drift_sd_frac``; the test's few minutes are short against its
  300 s correlation time, so one draw): the test is made on another occasion than each run;
* the hopper at the runs' initial fill (its level factor, ``level_sensitivity_frac``);
* the flutes' fill variation: every flute of every row discharges ``N`` times, each charge
  ``1 + flute_charge_sd_frac·z``, so the test's mean charge has an SD of
  ``flute_charge_sd_frac / sqrt(N·flutes·rows)`` (0.08 % for 50 revolutions of 12 flutes and
  4 rows);
* whole revolutions: the flute pulsation's harmonics cancel; the rollers' spread is drawn about
  the meter's mean (``row_spread_sd_frac``), so the test weighs mean 1;
* the scale: within ``scale_error_kg`` of the mass (uniform), read to ``scale_resolution_kg``.

The result is one row's grams per revolution at the test speed: what a controller turns into
its feedforward map (``reference_controllers/fertilizer/calibration.py``).

Example
-------
>>> from plant_emulators.fertilizer.config import load_rig_config
>>> cfg = load_rig_config()
>>> test = run_calibration_test(cfg, cfg.fertilizer.density_offset_mean_frac, seed_words=(7,))
>>> test.revolutions, test.shaft_speed_rpm
(50, 20.0)
>>> 90.0 < test.grams_per_rev_row < 100.0
True
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

from plant_emulators.fertilizer.config import FertilizerRigConfig
from plant_emulators.fertilizer.flow_map import FlowMap

__all__ = ["CalibrationTest", "lot_seed_words", "run_calibration_test"]

#: a stream of its own: the test's draws never share the run's generator
_STREAM = 0xCA11_B7E5


@dataclass(frozen=True)
class CalibrationTest:
    """One calibration test's outcome and what went into it.

    ``grams_per_rev_row`` is what the terminal sends; ``true_grams_per_rev_row`` is what the
    meter really delivered per revolution and row during the test (before the scale), and
    ``lot_grams_per_rev_row`` the lot's mean delivery at the test speed without the test's own
    draws (what a perfect test would read).
    """

    lot_frac: float
    revolutions: int
    shaft_speed_rpm: float
    weighed_kg: float
    grams_per_rev_row: float
    true_grams_per_rev_row: float
    lot_grams_per_rev_row: float

    @property
    def error_frac(self) -> float:
        """The test's error against the lot's mean delivery (what the controller inherits)."""
        return self.grams_per_rev_row / self.lot_grams_per_rev_row - 1.0

    def to_dict(self) -> dict[str, float | int]:
        return {"lot_frac": self.lot_frac, "revolutions": self.revolutions,
                "shaft_speed_rpm": self.shaft_speed_rpm, "weighed_kg": self.weighed_kg,
                "grams_per_rev_row": self.grams_per_rev_row,
                "true_grams_per_rev_row": self.true_grams_per_rev_row,
                "lot_grams_per_rev_row": self.lot_grams_per_rev_row,
                "error_frac": self.error_frac}


def lot_seed_words(lot_frac: float) -> tuple[int, int]:
    """The lot's value as two 32-bit words: the test of one lot is one test, whichever run of
    a campaign sample asks for it (each sample draws its own lot)."""
    bits = struct.unpack("<Q", struct.pack("<d", lot_frac))[0]
    return bits & 0xFFFFFFFF, bits >> 32


def run_calibration_test(config: FertilizerRigConfig, lot_frac: float, *,
                         seed_words: tuple[int, ...]) -> CalibrationTest:
    """The calibration test of the lot ``lot_frac`` on the rig ``config``.

    Parameters
    ----------
    config : FertilizerRigConfig
        The rig (meter, fertilizer, hopper and ``[calibration_test]``).
    lot_frac : float
        The lot's delivery offset against the meter's map (``density_offset_mean_frac``).
    seed_words : tuple of int
        The draws' seed (32-bit words): :func:`lot_seed_words` for a sample's lot.
    """
    test = config.calibration_test
    meter, fert = config.meter, config.fertilizer
    rng = np.random.default_rng(np.random.SeedSequence([*seed_words, _STREAM]))
    day = fert.density_offset_sd_frac * float(rng.standard_normal())
    wander = fert.density_drift_sd_frac * float(rng.standard_normal())
    charges = test.revolutions * meter.flutes * meter.rows
    flutes = meter.flute_charge_sd_frac / math.sqrt(charges) * float(rng.standard_normal())
    scale = float(rng.uniform(-test.scale_error_kg, test.scale_error_kg))
    fill = fert.hopper_initial_kg / fert.hopper_capacity_kg
    level = 1.0 - fert.level_sensitivity_frac * (1.0 - fill)
    n = test.shaft_speed_rpm
    map_g_rev = 60.0 * FlowMap.from_config(meter).flow_gps(n) / n
    lot_g_rev = map_g_rev * (1.0 + lot_frac) * level
    true_g_rev = map_g_rev * (1.0 + lot_frac + day + wander) * level * (1.0 + flutes)
    true_kg = true_g_rev * test.revolutions * meter.rows / 1000.0
    steps = round((true_kg + scale) / test.scale_resolution_kg)
    weighed_kg = max(steps, 0) * test.scale_resolution_kg
    return CalibrationTest(
        lot_frac=lot_frac, revolutions=test.revolutions, shaft_speed_rpm=n,
        weighed_kg=weighed_kg,
        grams_per_rev_row=weighed_kg * 1000.0 / (test.revolutions * meter.rows),
        true_grams_per_rev_row=true_g_rev, lot_grams_per_rev_row=lot_g_rev)
