"""The operator's calibration test as the reference's feedforward map: MeterCalibration in.

The terminal sends what the operator's calibration ("rotation") test weighed: one row's grams
per meter-shaft revolution at the test's shaft speed (``MeterCalibration`` of the rig's DBC;
``plant_emulators/fertilizer/calibration_test.py`` says what the test includes). The reference's
feedforward map is ``q = ff_coeff·n^ff_exponent`` g/s per row, linear below
``ff_linear_below_rpm`` (:func:`~reference_controllers.fertilizer.piecewise_pid.feedforward_volts`),
whose grams per revolution are ``60·q(n)/n``. The test fixes the map's coefficient, the
exponent (the meter's shape) staying::

    ff_coeff = g_rev / 60 · max(n, n_knee)^(1 - ff_exponent)

(below the knee the grams per revolution are constant, those of the knee). The C build
computes the same expression (``firmware/apps/fertilizer_adapter.c``): the same bits.

>>> round(ff_coeff_from_test(97.0, 21.0, 0.6537, 5.0), 4)
4.5239
>>> ff_coeff_from_test(0.0, 20.0, 0.6537, 5.0) is None        # no test
True
"""

from __future__ import annotations

import math

#: a coefficient above this is not a fluted roller's (the core's own bound on ff_coeff)
FF_COEFF_MAX = 100.0


def ff_coeff_from_test(grams_per_rev: float, shaft_rpm: float, ff_exponent: float,
                       ff_linear_below_rpm: float) -> float | None:
    """The feedforward map's coefficient from a calibration test, or None when the frame
    holds no usable test (no mass, no speed, or a coefficient no meter has)."""
    if not (grams_per_rev > 0.0 and shaft_rpm > 0.0):
        return None
    n_ref = shaft_rpm if shaft_rpm > ff_linear_below_rpm else ff_linear_below_rpm
    coeff = grams_per_rev / 60.0 * math.pow(n_ref, 1.0 - ff_exponent)
    if not 0.0 < coeff <= FF_COEFF_MAX:
        return None
    return coeff
