"""The sowing-depth rig as an ISOBUS tractor: a field run under a Task Controller (issue 42).

Variable-depth seeding: the seeding depth follows a prescription map (deeper where the soil
dries out, shallower in wet zones). When a scenario has a ``[tractor]`` table
(:class:`hil.rig.scenario.TractorRun`), the rig's terminal (DepthSetpoint) and its own
ground-speed frame give way to the emulated tractor (:class:`hil.isobus.tractor.Tractor`, the
fertilizer rig's, rig-agnostic): its tractor ECU reports the path's speed (PGN 65096 / 65097 /
61474) and its Task Controller sends the DUT, an ISOBUS implement, the map's depth as DDI 56
(set-point seeding depth, 1 mm per raw value: a map whose unit is ``mm``) ahead by the
set-point latency its DDOP declares. What the rig adds around the tractor:

- **motion**: the path is the truth of motion; the planter's ground speed is the path's, so the
  GNSS receiver on the serial line (the controller's speed source) and the TECU's speeds agree;
- **geometry**: the seed line, ``[machine] rows x row_spacing_mm`` wide, sits
  ``tractor_rear_axle_ahead_of_seed_m`` behind the GNSS antenna (the tractor's reference point,
  over its rear axle); the truth cells of the run are placed there, which the suite judges
  against the map;
- **faults**: ``tc_down`` and ``tecu_silent``, as on the fertilizer rig;
- **what the implement said**: every actual seeding depth (DDI 57) it sent the TC, and the
  default, minimum and maximum seeding depth its DDOP declares (DDI 58-60), for the suite to
  judge against the truth (what it reports; what it does without a TC).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hil.errors import ConfigError
from hil.isobus import ddi as dd
from hil.isobus.field import Boom, Field, Pose, PrescriptionMap, load_field, load_prescription
from hil.isobus.tractor import Tractor, TractorSetup, default_server_options
from hil.rig.device import Device
from hil.rig.scenario import TractorRun

__all__ = ["DEPTH_FIELD_FAULTS", "DepthFieldRun", "SeedLine"]

#: faults of a field run under the TC: name -> what it does
DEPTH_FIELD_FAULTS = {
    "tc_down": "the Task Controller loses power: silent and deaf until cleared, then it claims "
               "its address again and restarts",
    "tecu_silent": "the tractor ECU's speed messages (PGN 65096/65097/61474) stop",
}

#: the DDOP's declared depths the run keeps: key -> DDI
_DECLARED = {"default": dd.DEFAULT_SEEDING_DEPTH, "minimum": dd.MINIMUM_SEEDING_DEPTH,
             "maximum": dd.MAXIMUM_SEEDING_DEPTH}


@dataclass(frozen=True)
class SeedLine:
    """Where the seeds go: the rows' seed tubes across the working width.

    Attributes
    ----------
    width_m : float
        Working width (rows x row spacing).
    offset_m : float
        Fore-aft offset of the seed tubes from the GNSS antenna (negative: behind).
    """

    width_m: float
    offset_m: float

    def boom(self) -> Boom:
        """The seed line as one section (no look-ahead: the truth)."""
        return Boom.uniform(1, self.width_m, fore_aft_m=self.offset_m)

    def as_dict(self) -> dict[str, float]:
        return {"width_m": self.width_m, "offset_m": self.offset_m}


class DepthFieldRun:
    """The emulated tractor of one field run of the depth rig.

    Raises
    ------
    ConfigError
        The field or the map cannot be read, the map is not a depth map (unit ``mm``), or the
        scenario asks for the tractor's VT (the depth rig's field run has none).
    """

    def __init__(self, run: TractorRun, seed_line: SeedLine) -> None:
        if run.vt:
            # not silently ignored: a scenario that asks for the VT and its operator would
            # judge nothing of either on this rig
            raise ConfigError("the depth rig's field run has no Virtual Terminal (the "
                              "fertilizer rig's has): remove vt = true and the [[operator]] "
                              "steps", key="tractor.vt")
        self.run = run
        self.seed_line = seed_line
        self.field: Field = load_field(run.field)
        self.prescription: PrescriptionMap | None = (
            load_prescription(run.prescription, frame=self.field.frame)
            if run.prescription else None)
        if self.prescription is not None and self.prescription.unit.name != "mm":
            raise ConfigError(f"the depth rig's map must be a seeding-depth map (unit mm, "
                              f"DDI 56), got {self.prescription.unit.name!r}",
                              path=run.prescription, key="prescription.unit")
        self._geojson = {key: json.loads(Path(name).read_text(encoding="utf-8"))
                         for key, name in (("field_geojson", run.field),
                                           ("prescription_geojson", run.prescription)) if name}
        options = replace(default_server_options(), memory_bytes=run.tc_memory_bytes)
        self.tractor = Tractor(TractorSetup(self.field, self.prescription,
                                            drive_after_s=run.drive_after_s,
                                            wheel_slip=run.wheel_slip), options=options)
        self.device: Device = self.tractor.network
        self._line = seed_line.boom()
        #: the depths the implement's DDOP declares (DDI 58-60, mm), kept from the last pool
        #: the TC had active (a TC that goes down forgets its sessions)
        self._declared: dict[str, float] = {}

    def pose(self, time_s: float) -> Pose:
        """The antenna at run time ``time_s``."""
        return self.tractor.pose(time_s)

    def seed_point(self, pose: Pose) -> tuple[float, float]:
        """The middle of the seed line (local east, north, m) at ``pose``."""
        h = math.radians(pose.heading_deg)
        return (pose.east_m + self.seed_line.offset_m * math.sin(h),
                pose.north_m + self.seed_line.offset_m * math.cos(h))

    def prescribed_depth(self, pose: Pose) -> float:
        """The map's depth (mm) under the seed line at ``pose``; nan without a map."""
        if self.prescription is None:
            return math.nan
        centre = self._line.section_lines(pose.east_m, pose.north_m, pose.heading_deg)[1][0]
        return float(self.prescription.rate_at_local(centre[:, 0], centre[:, 1]).mean())

    def depth_at(self, east_m: np.ndarray, north_m: np.ndarray) -> np.ndarray:
        """The map's depth (mm) at local points."""
        if self.prescription is None:
            return np.full(np.shape(east_m), math.nan)
        return np.asarray(self.prescription.rate_at_local(east_m, north_m), dtype=float)

    def set_fault(self, name: str, active: bool, time_s: float) -> None:
        """Inject or clear a :data:`DEPTH_FIELD_FAULTS` fault (the tractor plays them)."""
        self._keep_declared()
        self.tractor.set_fault(name, active, time_s)

    def _keep_declared(self) -> None:
        """Keep the depths the active pool declares (DDI 58-60 of its first element that has
        any), before a fault may end its session."""
        for session in self.tractor.tc.sessions.values():
            pool = session.pool
            if pool is None:
                continue
            for element in pool.elements:
                found = {key: pool.property_value(element.element_number, ddi)
                         for key, ddi in _DECLARED.items()}
                if any(v is not None for v in found.values()):
                    self._declared = {k: float(v) for k, v in found.items() if v is not None}
                    return

    def reported_depths(self) -> dict[str, list[float]]:
        """Every actual seeding depth (DDI 57, mm) an implement sent the TC: ``t_s`` (run
        time it arrived), ``depth_mm``."""
        scale = self.prescription.unit.ddi_per_unit if self.prescription is not None else 1.0
        values = [v for v in self.tractor.tc.values if v.ddi == dd.ACTUAL_SEEDING_DEPTH]
        return {"t_s": [round(v.time_s, 6) for v in values],
                "depth_mm": [v.value / scale for v in values]}

    def truth(self) -> dict[str, object]:
        """What the suite needs besides the traces: geometry, files, the TC's events, what
        the implement reported and declared."""
        self._keep_declared()
        return {
            "seed_line": self.seed_line.as_dict(),
            "field": self.run.field,
            "prescription": self.run.prescription,
            **self._geojson,
            "drive_after_s": self.run.drive_after_s,
            "wheel_slip": self.run.wheel_slip,
            **self.tractor.run_record(),
            "reported_depth": self.reported_depths(),
            "declared_depth_mm": dict(self._declared),
        }
