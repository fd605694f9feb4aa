"""The emulated tractor: a TECU and a Task Controller driving a field path over a prescription map.

:class:`Tractor` puts the rig's ISOBUS control functions on one
:class:`~hil.isobus.network.IsobusNetwork` (a rig device, so the same object runs under the
lockstep clock in a rig and in real time under ``hil isobus serve``):

- the **tractor ECU** (:mod:`hil.isobus.tecu`) reports wheel-based, ground-based and machine
  selected speed from the path's ground speed; the wheel-based one over-reads by the wheel slip;
- the **Task Controller** (:mod:`hil.isobus.tc`) takes each implement's device descriptor
  object pool and, once it is active, sends it
  - the prescription map's rate where the boom will be after the element's declared set-point
    latency (DDI 142, when the DDOP has it) as the map's set-point DDI (e.g. DDI 6, mass per
    area), TC-GEO;
  - the section states from coverage (:class:`~hil.isobus.field.coverage.SectionControl`, with
    the turn-on and turn-off times the DDOP declares, DDI 205/206) as the condensed set-point
    work states (DDI 290-305), and the set-point work state (DDI 289), TC-SC;
- the **as-applied map**: every ``record_period_s`` the implement's last reported actual rate
  (the map's actual DDI, e.g. 7) and actual section states (DDI 161-176) at the path's position,
  which :meth:`Tractor.as_applied` returns as a record for the report and GIS tools.

Which sections a boom has and where they are come from the implement's DDOP (elements of type
section with their X/Y offsets, DDI 134/135, and widths, DDI 67 or 70); a DDOP without sections
is treated as one section as wide as its widest working width. A DDOP the tractor cannot make a
boom of (a section without a working width, no width at all, more than 256 sections) is refused
at activation with the standard's error codes (errors in the DDOP, the object named), so no
client's pool can fail the tractor later. A client's message or set-point that raises ends that
client's session (``client error`` in the TC's events), not the tractor: the TECU's speeds and
every other client go on.

An implement is its NAME: when another NAME takes its address, the TC ends its session and the
newcomer's values are not recorded as the implement's; :meth:`Tractor.as_applied` keeps the
record of the first implement that connected.

The TC's NAME is self-configurable (ISO 11783-5): when a lower NAME claims 0xF7 the TC moves to
a free address in 128-247, says so in its events (``address lost``, ``address claimed``), and its
clients find it there by its status, as they would a real TC that moved. Nothing reads a clock:
the run time arrives through the network's ``tick``.
"""

from __future__ import annotations

import math
from concurrent.futures import Executor
from dataclasses import dataclass, field

from hil.errors import ConfigError
from hil.isobus import ddi as dd
from hil.isobus import process_data as pd
from hil.isobus.ddop import DdopError, ObjectPool, PoolError
from hil.isobus.ddop.objects import DeviceElement, ElementType
from hil.isobus.faults import IsobusFaults
from hil.isobus.field.as_applied import AsAppliedRecord
from hil.isobus.field.boom import Boom, Section
from hil.isobus.field.coverage import SectionControl
from hil.isobus.field.path import Field, Pose
from hil.isobus.field.prescription import PrescriptionMap
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.tc.records import LoggedValue
from hil.isobus.tc.server import ServerOptions, TaskControllerServer
from hil.isobus.tc.setpoints import SetpointRequest
from hil.isobus.tecu import SpeedSource, TractorEcu, TractorState, add_tecu
from hil.isobus.transport import TransportTiming

__all__ = ["TC_ADDRESS", "TC_NAME", "Tractor", "TractorSetup", "boom_from_ddop",
           "default_server_options"]

TC_FUNCTION = 130
"""ISO 11783-1 function code of a Task Controller (industry group 2, any device class)."""
TC_ADDRESS = 0xF7
"""The Task Controller's preferred address (isobus.md)."""
TC_NAME = IsobusName(identity_number=0x1EE, manufacturer_code=0, function=TC_FUNCTION,
                     device_class=0, industry_group=2, self_configurable=True)
"""The rig's TC NAME (identity number arbitrary, manufacturer code 0: no manufacturer),
self-configurable: a TC that loses 0xF7 claims another address in 128-247 (ISO 11783-5)."""
TRACTOR_LOG_FRAMES = 2_000
"""Frames the tractor's network keeps in memory (its ``log``, for a look in a debugger): the
serve writes every frame to ``bus.log``, a rig's recorder its own log."""
MAX_SECTIONS = 256
"""Sections the condensed work states carry (16 DDIs of 16, ISO 11783-10)."""

#: DDIs the as-applied record reads from what the implement reports
_ACTUAL_RATE_FOR_SETPOINT = {dd.SETPOINT_MASS_PER_AREA_RATE: dd.ACTUAL_MASS_PER_AREA_RATE,
                             dd.SETPOINT_VOLUME_PER_AREA_RATE: dd.ACTUAL_VOLUME_PER_AREA_RATE,
                             dd.SETPOINT_COUNT_PER_AREA_RATE: dd.ACTUAL_COUNT_PER_AREA_RATE,
                             dd.SETPOINT_SEEDING_DEPTH: dd.ACTUAL_SEEDING_DEPTH}
_CONDENSED_SETPOINT = range(290, 306)
#: how many recent poses the tractor keeps (pose() is asked the same times within a tick)
_POSE_MEMO = 16
_CONDENSED_ACTUAL = range(161, 177)


@dataclass(frozen=True)
class TractorSetup:
    """What the emulated tractor drives and how.

    Attributes
    ----------
    field : Field
        The field: boundary, work area (the field less its headlands), path.
    prescription : PrescriptionMap or None
        The rate map (``None``: the TC sends no rate set-point, TC-BAS/SC only).
    drive_after_s : float
        Run time at which the tractor starts down the path (it stands at the path's start
        before, key on), so an implement can connect first.
    wheel_slip : float
        Slip of the tractor's driven wheels (0 <= slip < 1): the wheel-based speed over-reads.
    speed_source : SpeedSource
        What the machine selected speed carries.
    overlap_tolerance_pct : float
        Share of a section's ground that may be covered already before it is switched off.
    record_period_s : float
        How often the as-applied record samples the implement's reports.
    """

    field: Field
    prescription: PrescriptionMap | None = None
    drive_after_s: float = 0.0
    wheel_slip: float = 0.0
    speed_source: SpeedSource = SpeedSource.GROUND_BASED
    overlap_tolerance_pct: float = 50.0
    record_period_s: float = 0.1

    def __post_init__(self) -> None:
        if not (math.isfinite(self.drive_after_s) and self.drive_after_s >= 0):
            raise ValueError(f"drive_after_s must be >= 0 s, got {self.drive_after_s}")
        if not 0.0 <= self.wheel_slip < 1.0:
            raise ValueError(f"wheel_slip must be in [0, 1), got {self.wheel_slip}")
        if not (math.isfinite(self.record_period_s) and self.record_period_s > 0):
            raise ValueError(f"record_period_s must be > 0 s, got {self.record_period_s}")


@dataclass
class _Implement:
    """What the tractor keeps of one connected implement (one active DDOP)."""

    pool: ObjectPool
    boom: Boom
    sections: list[DeviceElement]
    control: SectionControl
    record: AsAppliedRecord | None
    name: int | None = None
    states_at_s: float = -math.inf
    actual_rate: dict[int, float] = field(default_factory=dict)
    actual_states: dict[int, int] = field(default_factory=dict)


def boom_from_ddop(pool: ObjectPool) -> tuple[Boom, list[DeviceElement]]:
    """The boom an implement's DDOP describes, and its section elements left to right.

    Sections are the elements of type section; their X/Y offsets (DDI 134/135, mm) and widths
    (DDI 67 actual or 70 maximum working width, mm) are read from their properties. The
    turn-on/turn-off look-ahead times are DDI 205/206 (ms) on any element.

    Raises
    ------
    DdopError
        (a ValueError) The pool has no section and no working width, a section without a
        width, or more than 256 sections; naming the element's object, with the activate
        response's codes (errors in the DDOP, any other error).
    """
    sections = [e for e in pool.elements if e.element_type == ElementType.SECTION]
    if len(sections) > MAX_SECTIONS:
        extra = sections[MAX_SECTIONS]
        raise DdopError(f"{len(sections)} section elements; the condensed work states carry "
                        f"{MAX_SECTIONS}", object_id=extra.object_id, parent_id=extra.parent_id,
                        pool_error=PoolError.ANY_OTHER_ERROR)
    turn_on = turn_off = 0.0
    for element in pool.elements:
        on = pool.property_value(element.element_number, dd.SC_SETPOINT_TURN_ON_TIME)
        off = pool.property_value(element.element_number, dd.SC_SETPOINT_TURN_OFF_TIME)
        turn_on = max(turn_on, (on or 0) / 1000.0)
        turn_off = max(turn_off, (off or 0) / 1000.0)

    def width_mm(element: DeviceElement) -> int | None:
        for ddi in (dd.ACTUAL_WORKING_WIDTH, dd.MAXIMUM_WORKING_WIDTH):
            value = pool.property_value(element.element_number, ddi)
            if value:
                return value
        return None

    def placed(element: DeviceElement, width: int) -> Section:
        """The element's width where its offsets (DDI 134/135, mm) place it."""
        x = pool.property_value(element.element_number, dd.DEVICE_ELEMENT_OFFSET_X) or 0
        y = pool.property_value(element.element_number, dd.DEVICE_ELEMENT_OFFSET_Y) or 0
        return Section(width / 1000.0, y / 1000.0, x / 1000.0)

    if not sections:
        # one working width and no sections (a seed line, a spreader): the element with the
        # widest width is the boom, where its offsets (DDI 134/135) place it from the
        # connector, as a section's are read below
        widest = max(((w, e) for e in pool.elements if (w := width_mm(e)) and w > 0),
                     key=lambda item: item[0], default=None)
        if widest is None:
            raise DdopError("the DDOP declares no section and no working width (DDI 67/70)",
                            object_id=pool.device.object_id)
        width, element = widest
        return Boom((placed(element, width),), turn_on, turn_off), []
    out = []
    for element in sections:
        width = width_mm(element)
        if not width or width < 0:
            raise DdopError(f"section element {element.element_number} has no working width "
                            f"(a DDI 67 or 70 property > 0 mm)", object_id=element.object_id,
                            parent_id=element.parent_id)
        out.append((placed(element, width), element))
    out.sort(key=lambda item: item[0].lateral_m)
    return (Boom(tuple(s for s, _ in out), turn_on, turn_off), [e for _, e in out])


class Tractor:
    """The tractor side of the bench on one network (see the module docstring).

    Parameters
    ----------
    setup : TractorSetup
        Field, map, slip, timing.
    faults : IsobusFaults, optional
        Faults the network injects into the implement's stack.
    options : ServerOptions, optional
        What the TC reports in its version message.
    checker : Executor, optional
        Where the TC parses and checks received pools (a thread, for a real-time serve: the
        TECU's messages stay on time meanwhile); ``None``: on the network's thread.
    """

    def __init__(self, setup: TractorSetup, *, faults: IsobusFaults | None = None,
                 options: ServerOptions | None = None,
                 checker: Executor | None = None) -> None:
        self.setup = setup
        options = options or default_server_options()
        # a transfer larger than the TC's memory (plus the command byte) is refused at its RTS
        self.network = IsobusNetwork(
            faults=faults, name="tractor", log_frames=TRACTOR_LOG_FRAMES,
            timing=TransportTiming(max_receive_bytes=max(options.memory_bytes + 1, 1 << 16)))
        self.tecu: TractorEcu = add_tecu(self.network, self.truth)
        tc_cf = self.network.add(TC_NAME, TC_ADDRESS, "TC")
        #: the TC's control function (its address claim)
        self.tc_function = tc_cf
        self.tc = TaskControllerServer(tc_cf, options=options, setpoints=self._setpoint,
                                       on_value=self._on_value, usable=check_usable,
                                       isolate_errors=True, checker=checker)
        tc_cf.run(self.tc)
        tc_cf.run(self)
        #: the implements with an active DDOP, by address
        self._implements: dict[int, _Implement] = {}
        #: the first implement that connected (its record is the run's as-applied map)
        self._first: _Implement | None = None
        self._next_record_s = 0.0
        self._poses: dict[float, Pose] = {}

    # -- the path ------------------------------------------------------------------------------

    def pose(self, time_s: float) -> Pose:
        """Where the antenna is at run time ``time_s``.

        The TECU, the TC's set-points and look-ahead and the rig ask for the same few times in
        one tick: the last :data:`_POSE_MEMO` are kept (a path sample costs ~0.1 ms).
        """
        t = max(0.0, time_s - self.setup.drive_after_s)
        memo = self._poses
        pose = memo.get(t)
        if pose is None:
            pose = self.setup.field.path.pose(t)
            if len(memo) >= _POSE_MEMO:
                del memo[next(iter(memo))]
            memo[t] = pose
        return pose

    def leg_spans(self, kind: str) -> list[tuple[float, float]]:
        """Run-time spans during which the tractor drives legs of ``kind`` (``pass``,
        ``overlap``, ``turn``, ``transit``), consecutive legs of a kind merged."""
        path = self.setup.field.path
        spans: list[tuple[float, float]] = []
        for i, leg in enumerate(path.legs):
            if leg.kind != kind:
                continue
            a, b = (t + self.setup.drive_after_s for t in path.leg_time_span(i))
            if spans and spans[-1][1] == a:
                spans[-1] = (spans[-1][0], b)
            else:
                spans.append((a, b))
        return spans

    def truth(self, time_s: float) -> TractorState:
        """What the TECU reports at ``time_s``."""
        pose = self.pose(time_s)
        return TractorState(ground_speed_mps=pose.speed_m_s, wheel_slip=self.setup.wheel_slip,
                            speed_source=self.setup.speed_source,
                            implement_start=pose.kind in ("pass", "overlap"),
                            ground_distance_m=pose.distance_m)

    # -- the TC's set-points -------------------------------------------------------------------

    def _implement(self, address: int) -> _Implement | None:
        session = self.tc.sessions.get(address)
        if session is None or session.pool is None:
            self._implements.pop(address, None)
            return None
        known = self._implements.get(address)
        if known is not None and known.pool is session.pool and known.name == session.name:
            return known
        if (self._first is not None and self._first.pool is session.pool
                and self._first.name == session.name):
            known = self._first          # the first implement back (a TC restart, a move)
        else:
            boom, sections = boom_from_ddop(session.pool)
            control = SectionControl(boom, self.setup.field.work_area,
                                     overlap_tolerance_pct=self.setup.overlap_tolerance_pct)
            unit = self.setup.prescription.unit.name if self.setup.prescription else "rate"
            record = AsAppliedRecord(boom, self.setup.field.frame, unit)
            known = _Implement(session.pool, boom, sections, control, record,
                               name=session.name)
            if self._first is None:
                self._first = known
        self._implements[address] = known
        return known

    def _section_states(self, implement: _Implement, time_s: float) -> tuple[bool, ...]:
        if implement.states_at_s != time_s:
            implement.control.update(time_s, self.pose)
            implement.states_at_s = time_s
        return implement.control.states

    def _setpoint(self, request: SetpointRequest) -> int | None:
        implement = self._implement(request.client_address)
        if implement is None:
            return None
        rx = self.setup.prescription
        if rx is not None and request.ddi == rx.unit.ddi:
            latency = implement.pool.property_value(request.element,
                                                    dd.PHYSICAL_SETPOINT_TIME_LATENCY) or 0
            pose = self.pose(request.time_s + latency / 1000.0)
            centre = implement.boom.section_lines(pose.east_m, pose.north_m,
                                                  pose.heading_deg)[1][0]
            rate = float(rx.rate_at_local(centre[:, 0], centre[:, 1]).mean())
            return int(rx.setpoint_ddi_value(rate))
        if request.ddi in _CONDENSED_SETPOINT:
            states = self._section_states(implement, request.time_s)
            first = (request.ddi - _CONDENSED_SETPOINT.start) * dd.SECTIONS_PER_CONDENSED_DDI
            chunk = [1 if s else 0 for s in states[first:first + dd.SECTIONS_PER_CONDENSED_DDI]]
            chunk += [3] * (dd.SECTIONS_PER_CONDENSED_DDI - len(chunk))
            return dd.pack_condensed_work_state(chunk)
        if request.ddi == dd.SETPOINT_WORK_STATE:
            return 1 if self.pose(request.time_s).kind in ("pass", "overlap") else 0
        return None

    # -- the as-applied record (an application on the TC's function) ---------------------------

    def next_due(self, now_s: float) -> float:
        """When the as-applied record samples next."""
        return self._next_record_s

    def _on_value(self, value: LoggedValue) -> None:
        """The TC's hook: keep the implement's last reported actual rate and section states."""
        implement = self._implement(value.address)
        if implement is None:
            return
        actual = _ACTUAL_RATE_FOR_SETPOINT.get(
            self.setup.prescription.unit.ddi if self.setup.prescription else -1)
        if value.ddi == actual:
            implement.actual_rate[value.element] = float(value.value)
        elif value.ddi in _CONDENSED_ACTUAL:
            implement.actual_states[value.ddi] = value.value & 0xFFFFFFFF

    def tick(self, now_s: float) -> None:
        """Sample the as-applied record when due."""
        if now_s < self._next_record_s:
            return
        self._next_record_s = now_s + self.setup.record_period_s
        pose = self.pose(now_s)
        for address in list(self._implements):
            try:
                self._sample(address, now_s, pose)
            except Exception as exc:   # one implement's data must not end the tractor
                self._implements.pop(address, None)
                self.tc.end_session(address, now_s, f"as-applied record: "
                                    f"{type(exc).__name__}: {exc}")

    def _sample(self, address: int, now_s: float, pose: Pose) -> None:
        implement = self._implement(address)    # None once its session ended
        if implement is None:
            return
        applying = self._applying(implement)
        implement.control.record(pose, applying)
        if implement.record is not None:
            rate = self._actual_rate(implement)
            implement.record.add(_Timed(now_s, pose), applying,
                                 [rate] * len(implement.boom.sections))

    def implement_address(self) -> int | None:
        """The address of the implement whose DDOP is active (the first, if several)."""
        for address in self.tc.sessions:
            if self._implement(address) is not None:
                return address
        return None

    def reported_states(self, address: int) -> tuple[bool, ...] | None:
        """The section states the implement at ``address`` last reported (DDI 161-176), one
        per section of its DDOP, left to right; ``None``: no DDOP active, or none reported."""
        implement = self._implement(address)
        if implement is None or not implement.actual_states:
            return None
        return tuple(self._applying(implement))

    def _applying(self, implement: _Implement) -> list[bool]:
        n = len(implement.boom.sections)
        if not implement.actual_states:
            return list(implement.control.states)
        out = []
        for j in range(n):
            ddi_index, slot = divmod(j, dd.SECTIONS_PER_CONDENSED_DDI)
            packed = implement.actual_states.get(_CONDENSED_ACTUAL.start + ddi_index)
            state = dd.unpack_condensed_work_state(packed)[slot] if packed is not None else 0
            out.append(state == 1)
        return out

    def _actual_rate(self, implement: _Implement) -> float:
        rx = self.setup.prescription
        if rx is None or not implement.actual_rate:
            return 0.0
        raw = max(implement.actual_rate.values())
        return raw / rx.unit.ddi_per_unit

    # -- faults of a field run -----------------------------------------------------------------

    def set_fault(self, name: str, active: bool, time_s: float) -> None:
        """Inject or clear a fault the tractor plays in a field run (``tc_down``: the TC
        powered off, and on again; ``tecu_silent``: the tractor ECU sends nothing).

        Raises
        ------
        ConfigError
            Another fault name (naming it).
        """
        if name == "tc_down":
            if active:
                self.tc.restart(time_s, down_s=math.inf)
            else:
                # powered again: it claims its address (ISO 11783-5) and then sends its status
                self.tc_function.claimer.start(time_s)
                self.tc.come_back(time_s)
        elif name == "tecu_silent":
            self.tecu.silent = active
        else:
            raise ConfigError(f"unknown fault {name!r}", key=name)

    # -- results -------------------------------------------------------------------------------

    def run_record(self) -> dict[str, object]:
        """The TC's events and the implements on the network, for a field run's truth."""
        return {
            "tc_events": [{"t": round(e.time_s, 6), "kind": e.kind.value,
                           "address": e.address, "detail": e.detail} for e in self.tc.events],
            "implements": {f"0x{a:02X}": f"0x{n:016X}"
                           for a, n in self.network.external().items()},
        }

    def as_applied(self, address: int | None = None) -> AsAppliedRecord | None:
        """The as-applied record of the implement at ``address`` (``None``: of the first
        implement that connected, whether still connected or not)."""
        if address is None:
            return self._first.record if self._first is not None else None
        implement = self._implements.get(address)
        return implement.record if implement else None


@dataclass(frozen=True)
class _Timed:
    """A pose stamped with the run time (the path's own time starts later)."""

    t_s: float
    pose: Pose

    def __getattr__(self, name: str) -> object:
        return getattr(self.pose, name)


def check_usable(pool: ObjectPool) -> None:
    """The TC's activation check that the tractor can work with ``pool`` (a boom of it).

    Raises
    ------
    DdopError
        What :func:`boom_from_ddop` finds, with the activate response's codes.
    """
    boom_from_ddop(pool)


def default_server_options() -> ServerOptions:
    """A TC-BAS + TC-GEO + TC-SC server with one boom of up to 16 sections."""
    options = (pd.VersionOption.DOCUMENTATION
               | pd.VersionOption.TC_GEO_WITH_POSITION_BASED_CONTROL
               | pd.VersionOption.IMPLEMENT_SECTION_CONTROL)
    return ServerOptions(options=int(options), booms=1, sections=16, channels=1)
