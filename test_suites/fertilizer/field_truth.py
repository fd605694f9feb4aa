"""What a field run under the Task Controller really applied, where: the truth the ``isobus``
suite judges against the prescription map (:mod:`hil.metrics.application_map`).

The rig records, 100 times a second, the antenna's pose (``east_m``, ``north_m``,
``heading_deg``) and each row's delivered mass (``delivered_<row>_g``: what has left the tube at
the furrow opener); its truth names the openers' geometry (``field_run.boom``), the field and
the map. Resampled to :data:`SAMPLE_S`, each row is a section of the metrics:

- where its opener is (the pose and the geometry, :meth:`hil.isobus.field.Boom.section_lines`)
  and how far it has travelled;
- what it applied from one sample to the next: the mass delivered meanwhile over the strip it
  crossed (``10 x g / m²`` = kg/ha), and whether it applied at all (:data:`APPLYING_SHARE` of
  the map's smallest non-zero rate);
- what the map prescribes under the opener, which zone that is, whether the ground needed
  applying (inside the work area and not covered by an earlier leg: ``needed_ground``).

Nothing here reads what the DUT or the TC said: only the mass that landed and where.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import shapely

from hil.isobus.field import Boom, Field, PrescriptionMap
from hil.isobus.field.coverage import needed_ground
from hil.isobus.field.laid import SAMPLE_S, Laid, field_geometry, laid_from_run
from hil.rig import RunResult

#: the applied rate smoothed over this much time for judging transitions (the suites' flow
#: window: the flute pulsation at 2.4-3.6 Hz keeps ~13 % of its amplitude over 1 s)
SMOOTH_S = 1.0
#: the map is judged at steady speed: the tractor's speed has not changed by more than
#: STEADY_TOL over the last STEADY_S. While it changes, what lands lags the speed by the tube's
#: transport (0.43 s) whatever the controller does (at the headland's -0.36 m/s² that is ~12 %
#: of the rate); speed transients are flow.field.transient_lag's to judge
STEADY_S = 2.0
STEADY_TOL = 0.01
#: where the ground that needs applying changes for less than this along a row's track (a
#: sliver between two passes' edges), no section control would switch: the sliver is ignored
MIN_SWITCH_M = 1.0


@dataclass(frozen=True)
class FieldArrays:
    """The (k, s) arrays of :mod:`hil.metrics.application_map` for one run (see the module)."""

    t_s: np.ndarray
    distance_m: np.ndarray
    width_m: np.ndarray
    mass_g: np.ndarray
    applied: np.ndarray
    applied_smooth: np.ndarray
    applying: np.ndarray
    prescribed: np.ndarray
    cell: np.ndarray
    needed: np.ndarray
    inside_work_area: np.ndarray
    steady: np.ndarray
    """(k,) the tractor's speed steady (see :data:`STEADY_S`) and not zero."""
    boom_distance_m: np.ndarray
    """(k, 1) distance the middle of the openers has travelled."""
    boom_prescribed: np.ndarray
    """(k, 1) the map's rate under the middle of the openers."""
    boom_applied_smooth: np.ndarray
    """(k, 1) what the applying rows laid together, over their strips, smoothed (kg/ha)."""
    boom_applying: np.ndarray
    """(k, 1) some row applied."""


class FieldTruth:
    """The truth of one field run (see the module docstring).

    Raises
    ------
    KeyError
        The run was not a field run under the TC (no ``field_run`` in its truth).
    """

    def __init__(self, result: RunResult) -> None:
        truth = result.record["truth"]
        if "field_run" not in truth:
            raise KeyError(f"{result.out_dir}: not a field run under a Task Controller (its "
                           f"scenario has no [tractor] table)")
        self.result = result
        self.run: dict[str, Any] = truth["field_run"]
        geometry = self.run["boom"]
        self.rows = int(geometry["rows"])
        self.boom = Boom.uniform(self.rows, float(geometry["width_m"]),
                                 fore_aft_m=float(geometry["opener_offset_m"]))
        self.field: Field
        self.prescription: PrescriptionMap | None
        self.field, self.prescription = field_geometry(self.run)
        self.drive_after_s = float(self.run["drive_after_s"])

    # --- the TC's events ------------------------------------------------------------------
    def events(self, kind: str) -> list[float]:
        """Times of the TC's events of ``kind`` (``activated``, ``refused`` …) for any client."""
        return [float(e["t"]) for e in self.run["tc_events"] if e["kind"] == kind]

    # --- the arrays -----------------------------------------------------------------------
    @cached_property
    def laid(self) -> Laid:
        """What the rows laid where (:func:`hil.isobus.field.laid.laid_from_run`)."""
        traces, _ = self.result.traces()
        return laid_from_run(self.run, traces)

    @cached_property
    def arrays(self) -> FieldArrays:
        """Every trace sample at :data:`SAMPLE_S`, from the start to the end of the run."""
        laid = self.laid
        t, centre = laid.t_s, laid.centre
        distance = np.vstack([np.zeros((1, self.rows)), np.cumsum(laid.travel_m[:-1], axis=0)])
        window = max(1, round(SMOOTH_S / SAMPLE_S))
        smooth = _smoothed_rate(laid.mass_g, laid.area_m2, window)
        middle = centre.mean(axis=1)                                        # (k, 2)
        boom_steps = np.linalg.norm(np.diff(middle, axis=0), axis=-1)
        boom_distance = np.concatenate([[0.0], np.cumsum(boom_steps)])[:, None]
        if self.prescription is not None:
            prescribed = self.prescription.rate_at_local(centre[..., 0], centre[..., 1])
            boom_prescribed = self.prescription.rate_at_local(middle[:, 0],
                                                              middle[:, 1])[:, None]
        else:
            prescribed = np.zeros((t.size, self.rows))
            boom_prescribed = np.zeros((t.size, 1))
        applying = laid.applying
        boom_mass = np.where(applying, laid.mass_g, 0.0).sum(axis=1, keepdims=True)
        boom_area = np.where(applying, laid.area_m2, 0.0).sum(axis=1, keepdims=True)
        boom_smooth = _smoothed_rate(boom_mass, boom_area, window)
        path_t = np.clip(t - self.drive_after_s, 0.0, None)
        samples = self.field.path.sample(path_t)
        needed = needed_ground(self.boom, laid.east_m, laid.north_m, laid.heading_deg,
                               samples.leg, applying, self.field.work_area)
        # standing at the start (before the drive), nothing is needed: the field starts
        # when the tractor moves
        needed[t < self.drive_after_s] = False
        needed = _without_slivers(needed, distance, MIN_SWITCH_M)
        inside = shapely.contains_xy(self.field.work_area, centre[..., 0], centre[..., 1])
        return FieldArrays(t, distance, laid.width_m, laid.mass_g, laid.rate, smooth, applying,
                           np.asarray(prescribed, dtype=float), laid.zone, needed,
                           np.asarray(inside, dtype=bool),
                           _steady(samples.speed_m_s, max(1, round(STEADY_S / SAMPLE_S))),
                           boom_distance, np.asarray(boom_prescribed, dtype=float),
                           boom_smooth, applying.any(axis=1, keepdims=True))

    def window(self, t0: float, t1: float) -> np.ndarray:
        """(k,) True for the samples in ``[t0, t1)``."""
        t = self.arrays.t_s
        return (t >= t0) & (t < t1)


def _steady(speed: np.ndarray, n: int) -> np.ndarray:
    """(k,) True where the speed is > 0 and within STEADY_TOL of itself over the last n."""
    out = speed > 0
    for lag in range(1, n + 1):
        before = np.concatenate([np.full(lag, np.nan), speed[:-lag]])
        with np.errstate(invalid="ignore"):
            out &= np.abs(before - speed) <= STEADY_TOL * speed
    return out


def _without_slivers(needed: np.ndarray, distance: np.ndarray, min_m: float) -> np.ndarray:
    """``needed`` with every interior run shorter than ``min_m`` along the track flipped."""
    out = needed.copy()
    for j in range(out.shape[1]):
        col, d = out[:, j], distance[:, j]
        edges = np.flatnonzero(col[1:] != col[:-1]) + 1
        bounds = [0, *edges.tolist(), col.size]
        for a, b in itertools.pairwise(bounds[1:-1]):
            if d[b] - d[a] < min_m:
                col[a:b] = not col[a]
    return out


def _smoothed_rate(mass: np.ndarray, area: np.ndarray, n: int) -> np.ndarray:
    """kg/ha over a centred window of ``n`` samples: the window's mass over its area."""
    kernel = np.ones(n)
    out = np.zeros_like(mass)
    for j in range(mass.shape[1]):
        m = np.convolve(mass[:, j], kernel, mode="same")
        a = np.convolve(area[:, j], kernel, mode="same")
        with np.errstate(divide="ignore", invalid="ignore"):
            out[:, j] = np.where(a > 0, 10.0 * m / a, 0.0)
    return out
