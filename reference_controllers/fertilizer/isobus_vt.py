"""The reference ISOBUS implement with its operator interface on a Virtual Terminal (issue 39).

:class:`IsobusVtFlowController` is :class:`~reference_controllers.fertilizer.isobus_mode.
IsobusFlowController` plus a VT client (:class:`hil.isobus.vt.client.VtClient`) on the same
control function, with the pool of :mod:`reference_controllers.fertilizer.operator_pool`:

- **it refuses to meter before its pool is active on a VT**, as a market implement does
  (the operator has no master switch, no alarm, no calibration without one): its policy,
  stated in the docs; and it meters only while the operator's **Master** is on (off at
  power-up; each release of the Master soft key toggles it);
- the **Calibration** mask's two inputs (grams per revolution, shaft speed of the test) are
  the operator's calibration test: the feedforward map's coefficient from then on
  (:meth:`FlowController.calibrate`, the same expression as the MeterCalibration frame);
- the **Run** mask shows the TC's rate set-point and each row's actual rate, refreshed every
  second (only values that changed are sent);
- a row switched on whose flow is lost (no valid report, or left out by the cross-row check)
  for :data:`ALARM_AFTER_S` while metering raises the **Alarm** mask ("Row N: flow lost");
  *Ack* returns to the Run mask; a row alarms again only after it has recovered.

The pool is stored on the VT under :data:`~reference_controllers.fertilizer.operator_pool.
VERSION_LABEL`, so after a VT restart the controller loads it instead of uploading it.

The C ISOBUS build (``firmware/isobus``, ``--param vt=yes``) is its twin, frame for frame
(``firmware/isobus/README.md``).

:func:`fertilizer_piecewise_pid_isobus_vt` makes it for a DUT profile's ``launch.inprocess``
(``dut_profiles/fertilizer-piecewise-pid-isobus-vt-daemon.toml``; the must-fail implements are
the same with ``vt_defect``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import can

from hil.dut import Controller
from hil.isobus.vt.client import MAINTENANCE_PERIOD_S, KeyEvent, VtClient
from hil.isobus.vt.messages import KeyActivation
from reference_controllers.fertilizer.isobus_mode import IsobusFlowController
from reference_controllers.fertilizer.operator_pool import (
    ALARM_TEXT_LENGTH,
    IDS,
    VERSION_LABEL,
    meter_vt_pool,
)
from reference_controllers.params import ParamError, ParamValue

ALARM_AFTER_S = 1.0
"""A row's flow lost this long while metering raises the alarm."""
DISPLAY_PERIOD_S = 1.0
"""How often the Run mask's values are refreshed (changed ones only)."""
DEFECTS = ("", "ignores-master", "no-alarm", "bad-pool", "no-reconnect", "meters-without-vt",
           "no-store", "slow-maintenance", "ignores-calibration")
"""Parameter ``vt_defect``: the must-fail implements made of the reference, each a defect a
real implement could have (empty: the reference): ``no-store`` never stores its pool on the
VT (so it uploads it again after a VT restart); ``slow-maintenance`` sends its working set
maintenance every 2 s instead of every second; ``ignores-calibration`` shows the calibration
entered on the VT but meters on its own map."""


class IsobusVtFlowController(IsobusFlowController):
    """The ISOBUS reference with its VT operator interface (see the module docstring)."""

    def __init__(self, law: str | None = None, params: Mapping[str, ParamValue] | None = None,
                 **kwargs: Any) -> None:
        merged = dict(params or {})
        defect = str(merged.pop("vt_defect", ""))
        if defect not in DEFECTS:
            raise ParamError(f"vt_defect must be one of {', '.join(repr(d) for d in DEFECTS)}, "
                             f"got {defect!r}")
        #: the must-fail defect (empty: the reference)
        self.defect = defect
        super().__init__(law, merged, **kwargs)
        self.name = f"{self.name}-vt" + (f"-{defect}" if defect else "")
        self.vt_pool = meter_vt_pool(self.row_count)
        pool_bytes = self.vt_pool.to_bytes()
        if defect == "bad-pool":      # the rate's output number names a font the pool lacks
            obj = self.vt_pool.get(IDS.rate_out)
            assert obj is not None
            raw = bytearray(pool_bytes)
            raw[obj.offset + 8:obj.offset + 10] = (0x7777).to_bytes(2, "little")
            pool_bytes = bytes(raw)
        self.vt = VtClient(self.port, [pool_bytes],
                           None if defect == "no-store" else VERSION_LABEL)
        self.vt.on_key = self._on_key
        self.vt.on_number = self._on_number
        self.port.run(self.vt)
        #: the operator's master switch (off at power-up)
        self.master_on = False
        #: the calibration test entered on the VT: (grams per revolution, shaft rpm)
        self.calibration: tuple[float, float] = (0.0, 21.0)
        self.alarm_row: int | None = None
        self._shown: dict[int, int] = {}
        self._next_display_s = 0.0
        self._lost_since: dict[int, float] = {}
        self._alarmed: set[int] = set()
        self._maintenance_due = math.inf

    # -- the operator --------------------------------------------------------------------------

    def _on_key(self, event: KeyEvent) -> None:
        if event.activation != KeyActivation.RELEASED:
            return
        if event.object_id == IDS.key_master:
            self.master_on = not self.master_on or self.defect == "ignores-master"
            self.vt.change_string_value(IDS.master_var, b"ON " if self.master_on else b"OFF")
        elif event.object_id == IDS.key_calibration:
            self.vt.change_active_mask(IDS.working_set, IDS.calibration)
        elif event.object_id in (IDS.key_back, IDS.key_ack):
            self.alarm_row = None
            self.vt.change_active_mask(IDS.working_set, IDS.run)

    def _on_number(self, object_id: int, value: int, time_s: float) -> None:
        grams, rpm = self.calibration
        if object_id == IDS.cal_grams_in:
            grams = value / 10.0
        elif object_id == IDS.cal_rpm_in:
            rpm = value / 10.0
        else:
            return
        self.calibration = (grams, rpm)
        if self.defect != "ignores-calibration":
            self.calibrate(grams, rpm)

    # -- the policy ----------------------------------------------------------------------------

    def metering(self) -> bool:
        """As the ISOBUS reference, and only with its pool active on a VT and Master on."""
        if self.defect == "meters-without-vt":
            return super().metering()
        return self.vt.state == "connected" and self.master_on and super().metering()

    # -- the step ------------------------------------------------------------------------------

    def step(self) -> list[can.Message]:
        """The ISOBUS reference's step, then the VT's: alarms, the Run mask's values."""
        if self.defect == "no-reconnect" and self.vt.connected_s is not None:
            self.vt.vt_status_s = None        # never notices the VT is gone
        out = super().step()
        if self.defect == "slow-maintenance":
            self._slow_maintenance()
        if self.vt.state == "connected":
            self._watch_rows()
            if self.clock_s >= self._next_display_s - 1e-9:
                self._next_display_s = self.clock_s + DISPLAY_PERIOD_S
                self._refresh()
        return out

    def _slow_maintenance(self) -> None:
        """The ``slow-maintenance`` defect: each maintenance message's next one a second
        later than due (every 2 s)."""
        due = self.vt._next_maintenance_s
        if math.isfinite(due) and due != self._maintenance_due:
            self.vt._next_maintenance_s = due + MAINTENANCE_PERIOD_S
            self._maintenance_due = self.vt._next_maintenance_s

    def _row_rate_kg_ha(self, row: int) -> float:
        speed = self.ground_speed()
        report = self.rows.reports.get(row)
        if speed is None or speed[1] < 0.05 or report is None or not self.metering():
            return 0.0
        return max(0.0, report.flow_gps / (0.1 * self.row_width_m * speed[1]))

    def _refresh(self) -> None:
        values = {IDS.rate_var: round(self.rate_kg_ha * 10)}
        for row in range(1, self.row_count + 1):
            values[IDS.row_var(row)] = round(self._row_rate_kg_ha(row) * 10)
        for var, value in values.items():
            if self._shown.get(var) != value:
                self._shown[var] = value
                self.vt.change_numeric_value(var, value)

    def _watch_rows(self) -> None:
        target = self.target_gps()
        metering = self.metering() and target > 0.0
        now = self.clock_s
        for row in range(1, self.row_count + 1):
            report = self.rows.reports.get(row)
            lost = metering and row in self.rows.active and (
                report is None or not self.rows.valid(report, target, self.steps - 1)
                or row in self.rows.excluded)
            if not lost:
                self._lost_since.pop(row, None)
                self._alarmed.discard(row)
                continue
            since = self._lost_since.setdefault(row, now)
            if now - since >= ALARM_AFTER_S - 1e-9 and row not in self._alarmed \
                    and self.defect != "no-alarm":
                self._alarmed.add(row)
                self.alarm_row = row
                text = f"Row {row}: flow lost".ljust(ALARM_TEXT_LENGTH).encode("latin-1")
                self.vt.change_string_value(IDS.alarm_var, text)
                self.vt.change_active_mask(IDS.working_set, IDS.alarm)


def fertilizer_piecewise_pid_isobus_vt(**params: ParamValue) -> Controller:
    """The ISOBUS reference with its VT operator interface, stepping on SYNC, for a DUT
    profile's ``launch.inprocess`` (its ``[parameters]`` as keywords; ``mode`` physical or
    paper-literal, ``vt_defect`` for the must-fail implements).

    Raises
    ------
    ValueError
        An unknown parameter or a bad value (named).
    """
    merged = dict(params)
    mode = str(merged.pop("mode", "physical"))
    try:
        if mode not in ("physical", "paper-literal"):
            raise ParamError(f"parameter 'mode' must be physical or paper-literal, got "
                             f"{mode!r}")
        return IsobusVtFlowController(mode, merged, step_on_sync=True)
    except ParamError as exc:
        raise ValueError(str(exc)) from exc
