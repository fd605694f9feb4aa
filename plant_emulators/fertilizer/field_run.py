"""The fertilizer rig as an ISOBUS tractor: a field run under a Task Controller (issue 27).

When a scenario has a ``[tractor]`` table (:class:`hil.rig.scenario.TractorRun`), the rig's
terminal (FertSetpoint) and speed frames give way to an emulated tractor
(:class:`hil.isobus.tractor.Tractor`): its tractor ECU reports the path's speed (PGN 65096 /
65097 / 61474) and its Task Controller sends the DUT, an ISOBUS implement, the prescription
map's rate and the section states of TC-SC. :class:`FieldRun` is that tractor plus what the rig
needs around it:

- **motion**: the path is the truth of motion. The tractor is where the path says at run time
  ``t`` and moves at the path's speed; the rig's ground-speed model follows that speed (for
  the planter's own Hall wheel, 0x185);
- **row clutches**: the rig has no clutch actuator on the bus, so the section states the DUT
  reports (DDI 161, actual condensed work state) drive the meter's row clutches, as the
  implement's clutch outputs would; until it reports any, the clutches stay engaged (the
  state of an unpowered clutch on the rig: what a controller that never switches leaves);
- **geometry**: the furrow openers of the rig's meter (``[boom]`` of its config: width, rows,
  fore-aft offset from the GNSS antenna), where the delivered fertilizer lands; the truth the
  ``isobus`` suite judges against the map;
- **faults**: ``tc_down`` (the TC restarts and stays silent and deaf until cleared),
  ``tecu_silent`` (the TECU's speed messages stop) and ``vt_down`` (the VT restarts and stays
  silent until cleared);
- **the Virtual Terminal** (``[tractor] vt = true``, issue 39): the VT beside the TC, the
  scenario's ``[[operator]]`` steps played on it, the screens the operator saw
  (:class:`hil.isobus.vt.fieldvt.FieldVt`); a step naming an object the implement's pool
  does not have is raised as a setup error at the rig's next step once the pool is active.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

from hil.errors import ConfigError
from hil.isobus.field import Boom, Field, Pose, PrescriptionMap, load_field, load_prescription
from hil.isobus.tractor import Tractor, TractorSetup, default_server_options
from hil.isobus.vt.fieldvt import FieldVt
from hil.rig.device import Device
from hil.rig.scenario import TractorRun

__all__ = ["FIELD_FAULTS", "BoomGeometry", "FieldRun"]

#: faults of a field run under the TC: name -> what it does
FIELD_FAULTS = {
    "tc_down": "the Task Controller loses power: silent and deaf until cleared, then it claims "
               "its address again and restarts",
    "tecu_silent": "the tractor ECU's speed messages (PGN 65096/65097/61474) stop",
    "vt_down": "the Virtual Terminal loses power ([tractor] vt = true): silent until cleared, "
               "its working sets' pools lost, its stored versions kept",
}


@dataclass(frozen=True)
class BoomGeometry:
    """Where the rig's meter rows put the fertilizer: one furrow opener per row, left to right.

    Attributes
    ----------
    width_m : float
        Working width of the rows together.
    rows : int
        Meter rows, one opener each, ``width_m / rows`` apart.
    opener_offset_m : float
        Fore-aft offset of the openers from the GNSS antenna (negative: behind).
    """

    width_m: float
    rows: int
    opener_offset_m: float

    @property
    def row_width_m(self) -> float:
        """The strip of ground one row covers."""
        return self.width_m / self.rows

    def boom(self) -> Boom:
        """The openers as a :class:`~hil.isobus.field.boom.Boom` (no look-ahead: the truth)."""
        return Boom.uniform(self.rows, self.width_m, fore_aft_m=self.opener_offset_m)

    def as_dict(self) -> dict[str, float | int]:
        """For the run record (the suite reads it back)."""
        return {"width_m": self.width_m, "rows": self.rows,
                "opener_offset_m": self.opener_offset_m}


class FieldRun:
    """The emulated tractor of one field run, and the row clutches it drives.

    Parameters
    ----------
    run : TractorRun
        The scenario's ``[tractor]`` table (file names absolute).
    geometry : BoomGeometry
        The rig's openers.

    Raises
    ------
    ConfigError
        The field or the map cannot be read (naming the file and the key).
    """

    def __init__(self, run: TractorRun, geometry: BoomGeometry) -> None:
        self.run = run
        self.geometry = geometry
        self.field: Field = load_field(run.field)
        self.prescription: PrescriptionMap | None = (
            load_prescription(run.prescription, frame=self.field.frame)
            if run.prescription else None)
        # the files as read, for the record: a record copied elsewhere still has its maps
        self._geojson = {key: json.loads(Path(name).read_text(encoding="utf-8"))
                         for key, name in (("field_geojson", run.field),
                                           ("prescription_geojson", run.prescription)) if name}
        options = replace(default_server_options(), memory_bytes=run.tc_memory_bytes)
        self.tractor = Tractor(TractorSetup(self.field, self.prescription,
                                            drive_after_s=run.drive_after_s,
                                            wheel_slip=run.wheel_slip), options=options)
        self.device: Device = self.tractor.network
        #: the VT beside the TC, with the scenario's operator (``[tractor] vt = true``)
        self.vt: FieldVt | None = (FieldVt(self.tractor.network, run.operator)
                                   if run.vt else None)
        self._openers = geometry.boom()
        #: row clutches (row 1 first), as the DUT last reported its sections
        self.clutches: tuple[bool, ...] = (True,) * geometry.rows
        #: notes for the record: (time, kind, detail)
        self.notes: list[tuple[float, str, str]] = []
        self._mismatch_noted = False

    # --- motion ---------------------------------------------------------------------------
    def pose(self, time_s: float) -> Pose:
        """The antenna at run time ``time_s``."""
        return self.tractor.pose(time_s)

    def prescribed_rate(self, pose: Pose) -> float:
        """The map's rate (kg/ha) under the middle of the openers at ``pose``; 0 without a map."""
        if self.prescription is None:
            return 0.0
        centre = self._openers.section_lines(pose.east_m, pose.north_m, pose.heading_deg)[1][0]
        return float(self.prescription.rate_at_local(centre[:, 0], centre[:, 1]).mean())

    # --- clutches -------------------------------------------------------------------------
    def update_clutches(self, time_s: float) -> tuple[bool, ...]:
        """The clutches from the DUT's last reported section states (kept when none).

        Raises
        ------
        ConfigError
            An operator step names an object the implement's pool (active now) lacks.
        """
        if self.vt is not None:
            self.vt.raise_problem()
        address = self.tractor.implement_address()
        if address is None:
            return self.clutches
        states = self.tractor.reported_states(address)
        if states is None:
            return self.clutches
        if len(states) != self.geometry.rows:
            if not self._mismatch_noted:
                self._mismatch_noted = True
                self.notes.append((time_s, "isobus-sections",
                                   f"the DUT's DDOP has {len(states)} sections, the meter "
                                   f"{self.geometry.rows} rows: the clutches stay as they are"))
            return self.clutches
        self.clutches = states
        return states

    # --- faults ---------------------------------------------------------------------------
    def set_fault(self, name: str, active: bool, time_s: float) -> None:
        """Inject or clear a :data:`FIELD_FAULTS` fault (the tractor plays them, the VT its
        own)."""
        if name == "vt_down":
            if self.vt is None:
                raise ConfigError("vt_down needs the tractor's VT: [tractor] vt = true",
                                  key=name)
            self.vt.set_down(active, time_s)
            return
        self.tractor.set_fault(name, active, time_s)

    # --- record ---------------------------------------------------------------------------
    def truth(self) -> dict[str, object]:
        """What the suite needs besides the traces: geometry, files, the TC's events."""
        return {
            "boom": self.geometry.as_dict(),
            "field": self.run.field,
            "prescription": self.run.prescription,
            **self._geojson,
            "drive_after_s": self.run.drive_after_s,
            "wheel_slip": self.run.wheel_slip,
            **self.tractor.run_record(),
            **({"vt": self.vt.record()} if self.vt is not None else {}),
        }
