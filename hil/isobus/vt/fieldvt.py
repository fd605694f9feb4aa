"""The Virtual Terminal of a field run: beside the tractor's TC, played by the scenario's operator.

A rig's field run (``[tractor] vt = true``) puts :class:`FieldVt` on the tractor's network:

- the VT (:func:`~hil.isobus.vt.server.add_vt`, version 4, a 480 px data mask), its version
  store in memory for the run (a VT restart keeps it, so the implement can load its pool
  instead of uploading it again);
- the scenario's ``[[operator]]`` steps, played at their run times
  (:class:`~hil.isobus.vt.operator.Operator`); a step whose time falls while the VT is down
  is not played (the operator has no screen), the later ones are played when it is back;
- when the implement's pool becomes active, the steps are checked against it
  (:func:`~hil.isobus.vt.operator.check_steps`): a step naming an object the pool does not
  have is a setup error, kept in :attr:`FieldVt.problem` for the rig to raise (a
  :class:`~hil.errors.ConfigError` naming the step and the object; ``hil run`` exits 2);
- the screens the operator saw (:class:`~hil.isobus.vt.screens.ScreenRecorder`, at most one
  per second for value changes, a new mask at once), and every change of the shown mask
  with its type (data or alarm mask), for the suites.

:meth:`FieldVt.record` is the VT's part of the run's record (``truth.field_run.vt``): the VT's
record (:func:`~hil.isobus.vt.screens.vt_record`), the masks shown, the steps played and
missed, and the screens' PNG images (base64), which the report shows as "What the operator
saw" (:mod:`hil.report.sections_vt`). The VT has no clock or thread of its own: a lockstep
run stays reproducible.
"""

from __future__ import annotations

import base64
import math
from collections.abc import Sequence
from typing import Any

from hil.errors import ConfigError
from hil.isobus.network import IsobusNetwork
from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.operator import Operator, check_steps
from hil.isobus.vt.screens import ScreenRecorder, vt_record
from hil.isobus.vt.server import VirtualTerminalServer, VtOptions, add_vt
from hil.isobus.vt.steps import OperatorScriptError, OperatorStep
from hil.isobus.vt.workingset import WorkingSet

__all__ = ["SCREEN_INTERVAL_S", "FieldVt", "alarm_masks"]

SCREEN_INTERVAL_S = 1.0
"""Least run time between two screens of value changes on one mask (the reference implement
refreshes its values every second; a new mask is drawn at once)."""


class FieldVt:
    """The VT of one field run (see the module docstring).

    Parameters
    ----------
    network : IsobusNetwork
        The tractor's network (the TC's).
    steps : sequence of OperatorStep
        The scenario's ``[[operator]]`` list.
    options : VtOptions, optional
        The VT (default: version 4, 480 px).
    """

    def __init__(self, network: IsobusNetwork, steps: Sequence[OperatorStep] = (),
                 options: VtOptions | None = None) -> None:
        self.vt: VirtualTerminalServer = add_vt(network, options)
        self.recorder = ScreenRecorder(self.vt, None, min_interval_s=SCREEN_INTERVAL_S,
                                       keep_images=True)
        self.steps = tuple(sorted(steps, key=lambda s: s.at_s))
        self.operator = Operator(self.vt)
        #: the setup error a step against the implement's pool makes (the rig raises it)
        self.problem: ConfigError | None = None
        #: (time, address, mask id, mask type) each time the shown mask changed
        self.masks: list[tuple[float, int, int, str]] = []
        #: (from, to) run times the VT was down (a fault); ``to`` inf while it still is
        self.down: list[tuple[float, float]] = []
        self._shown: dict[int, int] = {}
        self._checked: set[tuple[int, str]] = set()
        self.vt.on_change.append(self._on_change)
        self.operator.schedule(self.steps)

    # -- the implement's pool and what it shows ----------------------------------------------
    def _on_change(self, ws: WorkingSet, time_s: float, reason: str) -> None:
        if ws.pool is not None:
            key = (ws.address, ws.pool.sha256)
            if key not in self._checked and self.problem is None:
                self._checked.add(key)
                try:
                    check_steps(self.steps, ws.pool)
                except ConfigError as exc:
                    self.problem = OperatorScriptError(
                        f"{exc} (the implement's pool at 0x{ws.address:02X}, active at "
                        f"{time_s:g} s)")
        gone = reason in ("VT restarted", "working set gone")
        mask = ws.active_mask if ws.pool is not None and not gone else -1
        if self._shown.get(ws.address) != mask:
            self._shown[ws.address] = mask
            obj = ws.obj(mask) if mask >= 0 else None
            kind = obj.type.name.lower() if obj is not None else "none"
            self.masks.append((round(time_s, 6), ws.address, mask, kind))

    def raise_problem(self) -> None:
        """Raise the setup error the operator's steps made against the pool, if any."""
        if self.problem is not None:
            raise self.problem

    # -- the VT fails ----------------------------------------------------------------------
    def set_down(self, down: bool, time_s: float) -> None:
        """The VT loses power (silent, its working sets and their pools lost, its stored
        versions kept) or comes back (its status again, the operator's later steps)."""
        if down:
            if self.down and math.isinf(self.down[-1][1]):
                return
            self.down.append((time_s, math.inf))
            self.vt.restart(time_s, down_s=math.inf)
            return
        if not self.down or not math.isinf(self.down[-1][1]):
            return
        since = self.down[-1][0]
        self.down[-1] = (since, time_s)
        for step in self.steps:
            if since <= step.at_s < time_s:
                self.operator.missed.append((step.at_s, f"{step.what}: the VT was down"))
        # powered again: it claims its address (ISO 11783-5), then sends its status; the VT
        # is back now, not after 'inf' (restart() cleared the operator's timers: the later
        # steps go on its timeline again)
        self.vt.port.claimer.start(time_s)  # type: ignore[attr-defined]
        self.vt._down_until_s = time_s
        self.operator.schedule([s for s in self.steps if s.at_s >= time_s])

    # -- the record --------------------------------------------------------------------------
    def record(self) -> dict[str, Any]:
        """The VT's part of the run's record (JSON-ready; see the module docstring)."""
        out = vt_record(self.vt, self.recorder)
        out["masks"] = [{"t": t, "address": a, "mask": m, "type": k}
                        for t, a, m, k in self.masks]
        out["operator"] = [{"at_s": s.at_s, "what": s.what, **_target(s)} for s in self.steps]
        out["operator_missed"] = [{"t": round(t, 6), "why": why}
                                  for t, why in self.operator.missed]
        out["vt_down"] = [[a, None if math.isinf(b) else b] for a, b in self.down]
        out["screen_images"] = {name: base64.b64encode(png).decode("ascii")
                                for name, png in self.recorder.images.items()}
        return out


def _target(step: OperatorStep) -> dict[str, Any]:
    """The object a step acts on, for the suites (``press``/``enter``/``type``)."""
    for key in ("press", "enter", "type"):
        value = getattr(step, key)
        if value is not None:
            return {key: value, **({"value": step.value} if key == "enter" else {}),
                    **({"hold_s": step.hold_s} if key == "press" else {})}
    return {}


def alarm_masks(record: dict[str, Any]) -> list[tuple[float, int]]:
    """(time, mask id) each time an alarm mask was shown, from :meth:`FieldVt.record`."""
    alarm = ObjectType.ALARM_MASK.name.lower()
    return [(float(m["t"]), int(m["mask"])) for m in record.get("masks", [])
            if m.get("type") == alarm]
