"""What a Task Controller asks of the field each period: set-points and section states.

:class:`FieldTask` ties a field (its path and work area), a prescription map and the boom the
implement's DDOP describes. A TC server calls :meth:`FieldTask.command` at each instant for the
rate set-point under each section and the section states to command, and
:meth:`FieldTask.report` with what the implement says it did (actual work states and rates), which
is what the coverage and the as-applied record are built from.

The rate set-point of a section is the map's rate where the section will be ``rate_lookahead_s``
from now: the implement's declared set-point latency (ISO 11783-11 "Physical Setpoint Time
Latency"), so that the rate changes where the zone does.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hil.isobus.field.as_applied import AsAppliedRecord
from hil.isobus.field.boom import Boom
from hil.isobus.field.coverage import PoseLike, SectionControl
from hil.isobus.field.path import Field, Pose
from hil.isobus.field.prescription import PrescriptionMap

__all__ = ["Command", "FieldTask"]


@dataclass(frozen=True)
class Command:
    """What the TC sends at one instant."""

    t_s: float
    pose: Pose
    """Where the tractor's antenna is (the path's pose at ``t_s``)."""
    rates: np.ndarray
    """Per section, the rate set-point in the map's unit."""
    rates_ddi: np.ndarray
    """The same as raw values of the map unit's set-point DDI (6 or 1)."""
    sections_on: tuple[bool, ...]
    """Per section, the commanded state (set-point work state)."""


class FieldTask:
    """A field, a map and a boom: set-points and section commands at any instant.

    Parameters
    ----------
    fld : Field
        The field and the path the tractor drives.
    rx_map : PrescriptionMap
        In the same frame as the field (``frame=fld.frame``).
    boom : Boom
        Sections and look-ahead times from the implement's DDOP.
    overlap_tolerance_pct : float
        Section control's overlap tolerance (:class:`~.coverage.SectionControl`).
    rate_lookahead_s : float
        The implement's set-point latency, >= 0.
    pose_at : callable, optional
        Future poses for the look-ahead; by default the field path's (a TC without the path
        passes a dead reckoning from its last fix, :func:`~.coverage.dead_reckoning`).
    """

    def __init__(self, fld: Field, rx_map: PrescriptionMap, boom: Boom, *,
                 overlap_tolerance_pct: float = 50.0, rate_lookahead_s: float = 0.0,
                 pose_at: Callable[[float], PoseLike] | None = None) -> None:
        if rx_map.frame != fld.frame:
            raise ValueError("the map and the field must share one frame (frame=fld.frame)")
        if not rate_lookahead_s >= 0:
            raise ValueError("rate_lookahead_s must be >= 0")
        self.field = fld
        self.map = rx_map
        self.boom = boom
        self.rate_lookahead_s = rate_lookahead_s
        self.control = SectionControl(boom, fld.work_area,
                                      overlap_tolerance_pct=overlap_tolerance_pct)
        self._pose_at = pose_at or fld.path.pose
        self.as_applied = AsAppliedRecord(boom, fld.frame, rx_map.unit.name)

    def command(self, t_s: float) -> Command:
        """Set-points and section states at run time ``t_s`` (call with increasing times)."""
        states = self.control.update(t_s, self._pose_at)
        ahead = self._pose_at(t_s + self.rate_lookahead_s)
        _, centres, _ = self.boom.section_lines(ahead.east_m, ahead.north_m, ahead.heading_deg)
        rates = self.map.rate_at_local(centres[0, :, 0], centres[0, :, 1])
        return Command(t_s, self.field.path.pose(t_s), rates, self.map.setpoint_ddi_value(rates),
                       states)

    def report(self, pose: Pose, applying: Sequence[bool], rates: ArrayLike) -> None:
        """What the implement did from ``pose`` on: its actual work states and rates."""
        self.control.record(pose, applying)
        self.as_applied.add(pose, applying, rates)
