"""[F]'s flow controller as an ISOBUS implement: rate and sections from a Task Controller, speed
from the tractor ECU (issue 27).

The control law is the one of :mod:`reference_controllers.fertilizer.adapter` (the same
:class:`~reference_controllers.fertilizer.piecewise_pid.PiecewisePid`, the same flow module
frames 0x181-0x184 in, the same AnalogOutputCommand 0x220, ControllerStatus 0x190 and
heartbeat 0x710 out); only where the set-point comes from changes. Instead of agrihil's
FertSetpoint frame (0x210, ignored here) the controller hosts an implement control function on
its own :class:`~hil.isobus.network.IsobusNetwork`:

* **NAME** industry group 2, device class 5 (fertilizers), function 128 (rate control, device
  class dependent: ISO 11783-1 as AgIsoStack++'s ``NAME::Function`` carries it),
  self-configurable, preferred address 0x81 (parameter ``address``);
* **DDOP** (:func:`meter_pool`): the device, one boom (function element) and one section per
  meter row; the boom carries the rate set-point and actual (DDI 6/7), the work states
  (DDI 141, 289, condensed 161/290), its working width (67), offsets (134/135), the look-ahead
  times (205/206) and the set-point latency (142); each section its width and offsets;
* a :class:`~hil.isobus.tc_client.TaskControllerClient` connects to the TC; DDI 6 (mg/m²) is the
  target rate M (1 kg/ha = 100 mg/m² = 1 kg/hm²), DDI 290 switches rows (a section per row),
  DDI 289 = 0 stops the whole boom;
* ground speed from PGN 65097 (ground-based), PGN 65096 (wheel-based) only while no fresh
  65097 is heard; a speed older than :data:`SPEED_TIMEOUT_S` is lost.

The per-row target is [F] eq. 1 with the FertSetpoint semantics of ActiveRows: the rows that are
on share ``Q = 0.1·M·D·v`` over the width ``D`` they cover, so each active row delivers
``0.1·M·(D_total / rows)·v`` whatever the others do, and the flow modules of rows that are off
no longer count in the measured mean. The actual rate reported to the TC (DDI 7) is that mean
turned back into kg/ha through the same equation.

**Losing the TECU's speed** stops metering (0 V): the rig's speed-loss fault
(``flow.fault.speed_loss.overdelivery``: fertilizer delivered while the machine stands still)
judges that, and a meter cannot keep a per-area rate without a speed. **Losing the TC** (no
status for 6 s, a restart the TC announces with a NACK, a refused pool) also stops metering
until the pool is active again: without the TC there is neither a rate set-point (TC-GEO) nor
coverage (TC-SC), the TC's section control is no longer in automatic mode, and ISO 11783-10
then leaves the sections to the operator (manual mode), whom the rig does not have. Holding the
last rate and sections would keep applying over ground the TC may already have covered, which
is the overlap TC-SC exists to prevent. The DDOP declares no default rate (DDI 8), so there is
no other value the standard would have it fall back to.

Time: the network never reads a clock. The controller's time is its control step count times
its period (in lockstep one step per SYNC, so run time = SYNC count x 0.1 s); frames that
arrive between two steps are stamped with the time of the last step, and each step first sends
what the network answered to them (a CTS, a reply to a request) and what is due by then: the
controller sends only in its step, as a firmware's 100 ms task does (ISO 11783-3's response
time Tr is 200 ms), so in lockstep nothing it sends straddles two steps. Free-running (a
daemon's ``--period-ms``), the same count is the controller's own tick clock, as a firmware's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import can

from hil.isobus import ddi as dd
from hil.isobus.can_id import decode_id, make_frame
from hil.isobus.ddop import ElementType, ObjectPool, PoolBuilder, TriggerMethod
from hil.isobus.name import IsobusName
from hil.isobus.port import GLOBAL_ADDRESS, Received
from hil.isobus.process_data import PROCESS_DATA_PGN, WORKING_SET_MASTER_PGN, AckError
from hil.isobus.tecu import PGN_GROUND_BASED_SPEED, PGN_WHEEL_BASED_SPEED, iso11783_7_database
from plant_emulators.fertilizer.config import FertilizerRigConfig, load_rig_config
from reference_controllers.fertilizer.adapter import (
    MODE_FIELD,
    SYNC_ID,
    FlowController,
)
from reference_controllers.fertilizer.rows import FlowRows, Measurement
from reference_controllers.fertilizer.speeds import MAX_VALID_SPEED_MPS
from reference_controllers.isobus_implement import TcImplement, check_address
from reference_controllers.isobus_implement import implement_name as shared_implement_name
from reference_controllers.params import ParamError, ParamValue, field_names, override, split

__all__ = ["SPEED_TIMEOUT_S", "IsobusFlowController", "IsobusParams", "implement_name",
           "meter_pool"]

SPEED_TIMEOUT_S = 0.3
"""A TECU speed older than this is lost (isobus.md: AgIsoStack++'s choice; three missed
100 ms messages)."""
RATE_CONTROL_FUNCTION = 128
"""ISO 11783-1 function "rate control" (industry group 2, device-class dependent)."""
DEVICE_CLASS_FERTILIZERS = 5
MG_PER_M2_PER_KG_HA = 100.0
"""1 kg/ha = 10^6 mg / 10^4 m² = 100 mg/m² (DDI 6/7 units); 1 kg/hm² = 1 kg/ha."""
MAX_RATE_KG_HA = 1000.0
"""The largest rate the meter takes: FertSetpoint's TargetRate range, [0, 1000] kg/hm²."""
BOOM_OFFSET_X_MM = -1500
"""Estimate: the furrow openers 1.5 m behind the tractor's reference point (the rig's meter
sits on a trailed planter; [F] gives no geometry)."""
MIN_REPORT_SPEED_MPS = 0.05
"""Below this speed the actual rate per area is not defined (flow over ~no area): reported 0."""

_DENSE_ON_OR_TIME = TriggerMethod.ON_CHANGE | TriggerMethod.TIME_INTERVAL


@dataclass(frozen=True)
class IsobusParams:
    """The ISOBUS side's parameters (a DUT profile's ``[parameters]`` may set each).

    Attributes
    ----------
    address : float
        Preferred source address (0x81 = 129).
    identity_number : float
        The NAME's identity number (21 bits).
    width_m : float
        Working width D of the boom (the rig's field scenarios: 3 m); each row covers
        ``width_m / rows``.
    speed : str
        ``"ground"``: PGN 65097, PGN 65096 only while no fresh 65097 is heard (the reference);
        ``"wheel"``: PGN 65096 only (a controller that reads wheel-based speed through slip,
        for the suite's must-fail profile).
    ddop : str
        ``"valid"``, or ``"broken"``: a DDOP whose actual rate names a value presentation that
        is not in the pool, which a strict TC refuses (the must-fail profile).

    The rest make the suite's must-fail DUTs out of the reference, each a defect a real
    implement could have; the defaults are the reference.

    fixed_rate_kg_ha : float
        > 0: meter this rate whatever the TC sends (ignores the map).
    sections : str
        ``"tc"``: the TC's section states (DDI 290); ``"all"``: every row always on;
        ``"latch-off"``: a row the TC switches off never comes on again.
    without_tc_rate_kg_ha : float
        > 0: meter this rate on every row while no pool is active (no TC, or a refused pool),
        instead of stopping.
    reconnect : str
        ``"yes"``; ``"never"``: once the TC is lost, stop listening for it.
    speed_timeout_s : float
        A TECU speed older than this is lost (:data:`SPEED_TIMEOUT_S`); a large value holds
        the last speed heard.
    claim_first : str
        ``"yes"``; ``"no"``: send the working-set master message from the preferred address
        before claiming it.
    """

    address: float = 0x81
    identity_number: float = 0x0F27
    width_m: float = 3.0
    speed: str = "ground"
    ddop: str = "valid"
    fixed_rate_kg_ha: float = 0.0
    sections: str = "tc"
    without_tc_rate_kg_ha: float = 0.0
    reconnect: str = "yes"
    speed_timeout_s: float = SPEED_TIMEOUT_S
    claim_first: str = "yes"

    def __post_init__(self) -> None:
        check_address(self.address, self.identity_number)
        if not (math.isfinite(self.width_m) and 0.0 < self.width_m <= 30.0):
            raise ValueError(f"width_m must be within (0, 30] m, got {self.width_m}")
        if self.speed not in ("ground", "wheel"):
            raise ValueError(f"speed must be ground or wheel, got {self.speed!r}")
        if self.ddop not in ("valid", "broken"):
            raise ValueError(f"ddop must be valid or broken, got {self.ddop!r}")
        for name in ("fixed_rate_kg_ha", "without_tc_rate_kg_ha"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= MAX_RATE_KG_HA):
                raise ValueError(f"{name} must be within [0, {MAX_RATE_KG_HA:g}] kg/ha, "
                                 f"got {value}")
        if self.sections not in ("tc", "all", "latch-off"):
            raise ValueError(f"sections must be tc, all or latch-off, got {self.sections!r}")
        if self.reconnect not in ("yes", "never"):
            raise ValueError(f"reconnect must be yes or never, got {self.reconnect!r}")
        if not (self.speed_timeout_s > 0.0 and not math.isnan(self.speed_timeout_s)):
            raise ValueError(f"speed_timeout_s must be > 0 s, got {self.speed_timeout_s}")
        if self.claim_first not in ("yes", "no"):
            raise ValueError(f"claim_first must be yes or no, got {self.claim_first!r}")


def implement_name(identity_number: int) -> IsobusName:
    """The controller's NAME: agriculture, fertilizers, rate control, self-configurable."""
    return shared_implement_name(identity_number, device_class=DEVICE_CLASS_FERTILIZERS,
                                 function=RATE_CONTROL_FUNCTION)


@dataclass(frozen=True)
class MeterElements:
    """Element numbers of the DDOP's boom and sections (row 1 first)."""

    boom: int
    sections: tuple[int, ...]


def meter_pool(*, name: int, width_m: float, rows: int, latency_ms: int,
               broken: bool = False) -> tuple[ObjectPool, MeterElements]:
    """The meter's device descriptor object pool and its element numbers.

    Parameters
    ----------
    name : int
        The client's 64-bit NAME, carried by the device object.
    width_m : float
        The boom's working width; ``rows`` sections of ``width_m / rows`` side by side,
        section 1 on the left (ISO 11783-10: Y positive to the right of travel).
    rows : int
        Meter rows, one section each (1 .. 16: one condensed work state DDI).
    latency_ms : int
        Physical set-point latency (DDI 142) and the section look-ahead times (205/206): how
        long a change of the meter takes to reach the ground.
    broken : bool
        Give DDI 7 a value presentation that does not exist (an invalid pool, not validated).

    Raises
    ------
    ValueError
        ``rows`` outside 1 .. 16.
    """
    if not 1 <= rows <= dd.SECTIONS_PER_CONDENSED_DDI:
        raise ValueError(f"rows must be 1 .. {dd.SECTIONS_PER_CONDENSED_DDI}, got {rows}")
    b = PoolBuilder(version=4)
    dvc = b.device("agrihil fertilizer meter", software_version="1.0.0", name=name,
                   serial_number="1", structure_label=b"AGF-BRK" if broken else b"AGF-ISO")
    mm = b.presentation("mm")
    ms = b.presentation("ms")
    kg_ha = b.presentation("kg/ha", scale=0.01, decimals=1)
    device = b.element(ElementType.DEVICE, "Fertilizer meter", parent=dvc)
    boom = b.element(ElementType.FUNCTION, "Boom", parent=device)
    width_mm = round(width_m * 1000)
    b.property(boom, ddi=dd.ACTUAL_WORKING_WIDTH, value=width_mm, designator="Working width",
               presentation=mm)
    b.property(boom, ddi=dd.DEVICE_ELEMENT_OFFSET_X, value=BOOM_OFFSET_X_MM,
               designator="Offset X", presentation=mm)
    b.property(boom, ddi=dd.DEVICE_ELEMENT_OFFSET_Y, value=0, designator="Offset Y",
               presentation=mm)
    b.property(boom, ddi=dd.SC_SETPOINT_TURN_ON_TIME, value=latency_ms,
               designator="Turn on time", presentation=ms)
    b.property(boom, ddi=dd.SC_SETPOINT_TURN_OFF_TIME, value=latency_ms,
               designator="Turn off time", presentation=ms)
    b.property(boom, ddi=dd.PHYSICAL_SETPOINT_TIME_LATENCY, value=latency_ms,
               designator="Setpoint latency", presentation=ms)
    b.process_data(boom, ddi=dd.SETPOINT_MASS_PER_AREA_RATE, designator="Target rate",
                   settable=True, presentation=kg_ha)
    b.process_data(boom, ddi=dd.ACTUAL_MASS_PER_AREA_RATE, designator="Actual rate",
                   triggers=_DENSE_ON_OR_TIME, presentation=0x7FFF if broken else kg_ha)
    b.process_data(boom, ddi=dd.ACTUAL_WORK_STATE, designator="Actual work state",
                   triggers=_DENSE_ON_OR_TIME)
    b.process_data(boom, ddi=dd.SETPOINT_WORK_STATE, designator="Setpoint work state",
                   settable=True)
    actual, _ = dd.condensed_work_state_ddi(0, setpoint=False)
    setpoint, _ = dd.condensed_work_state_ddi(0, setpoint=True)
    b.process_data(boom, ddi=actual, designator="Actual work state 1-16",
                   triggers=_DENSE_ON_OR_TIME)
    b.process_data(boom, ddi=setpoint, designator="Setpoint work state 1-16", settable=True)
    row_mm = width_mm // rows
    section_ids = []
    for i in range(rows):
        section = b.element(ElementType.SECTION, f"Row {i + 1}", parent=boom)
        section_ids.append(section)
        # ISO 11783-10: every element's offsets are from the device's reference point, not
        # from its parent: the sections sit where the boom does
        b.property(section, ddi=dd.DEVICE_ELEMENT_OFFSET_X, value=BOOM_OFFSET_X_MM,
                   designator="Offset X", presentation=mm)
        b.property(section, ddi=dd.DEVICE_ELEMENT_OFFSET_Y,
                   value=-width_mm // 2 + i * row_mm + row_mm // 2, designator="Offset Y",
                   presentation=mm)
        b.property(section, ddi=dd.ACTUAL_WORKING_WIDTH, value=row_mm, designator="Width",
                   presentation=mm)
    pool = b.build(validate=not broken)
    number = {e.object_id: e.element_number for e in pool.elements}
    return pool, MeterElements(number[boom], tuple(number[s] for s in section_ids))


class SectionRows(FlowRows):
    """The flow modules of the rows that are on; remembers the last measurement."""

    def __init__(self, stale_after_s: float, period_s: float, rows: int) -> None:
        super().__init__(stale_after_s, period_s)
        self.active = set(range(1, rows + 1))
        self.last = Measurement(0.0, False, False, 0)

    def report(self, row: int, flow_gps: float, baseline_ready: bool, overrange: bool,
               step: int) -> None:
        if row in self.active:
            super().report(row, flow_gps, baseline_ready, overrange, step)

    def switch(self, active: set[int]) -> None:
        """Only ``active`` rows count from now on (a row switched off is forgotten)."""
        for row in set(self.reports) - active:
            del self.reports[row]
        self.active = set(active)

    def measure(self, target_gps: float, step: int,
                active_rows: int | None = None) -> Measurement:
        """The rows switched on by the TC count (:meth:`switch`); FertSetpoint's
        ``active_rows`` is not listened to."""
        self.last = super().measure(target_gps, step)
        return self.last


class IsobusFlowController(FlowController):
    """The reference flow controller as an ISOBUS implement (see the module docstring).

    Parameters
    ----------
    law : str, optional
        ``"physical"`` (default) or ``"paper-literal"``.
    params : mapping, optional
        :class:`IsobusParams` fields, and whatever :class:`FlowController` takes.
    step_on_sync : bool
        One control step per SYNC (lockstep).
    rig_config : FertilizerRigConfig, optional
        The rig's configuration: rows (sections) and transport delays (the set-point latency).
    **more_params
        More parameters as keywords.

    Raises
    ------
    ParamError
        An unknown parameter or a bad value, named.
    """

    def __init__(self, law: str | None = None, params: Mapping[str, ParamValue] | None = None,
                 *, step_on_sync: bool = True, rig_config: FertilizerRigConfig | None = None,
                 **more_params: ParamValue) -> None:
        mine, rest = split({**(params or {}), **more_params}, field_names(IsobusParams))
        self.isobus = override(IsobusParams(), mine)
        if (law or rest.get("mode")) == "open-loop":
            raise ParamError("the ISOBUS mode runs the closed-loop laws (physical, "
                             "paper-literal), not open-loop")
        if "ground_speed_first_s" in rest:
            raise ParamError("parameter 'ground_speed_first_s' is the terminal mode's: the "
                             "ISOBUS mode always prefers PGN 65097 (choose with 'speed' and "
                             "'speed_timeout_s')")
        if "use_calibration" in rest:
            raise ParamError("parameter 'use_calibration' is the terminal mode's: the ISOBUS "
                             "mode's calibration comes from the Virtual Terminal")
        config = rig_config or load_rig_config()
        super().__init__(law, rest, step_on_sync=step_on_sync, rig_config=config)
        self.name = f"{self.name}-isobus"
        self.row_count = config.meter.rows
        self.row_width_m = self.isobus.width_m / self.row_count
        transport = config.transport
        #: meter to furrow: the fall to the sensor and on down the tube to the opener
        self.latency_ms = round((transport.meter_to_sensor_delay_s
                                 + transport.sensor_to_exit_delay_s) * 1000.0)
        self.rows = SectionRows(self.adapter_params.stale_after_s, self.adapter_params.period_s,
                                self.row_count)
        self.implement_name = implement_name(int(self.isobus.identity_number))
        self.pool, self.elements = meter_pool(
            name=self.implement_name.value, width_m=self.isobus.width_m, rows=self.row_count,
            latency_ms=self.latency_ms, broken=self.isobus.ddop == "broken")
        self.implement = TcImplement(network_name=self.name, name=self.implement_name,
                                     address=int(self.isobus.address), label="fertilizer meter",
                                     pool=self.pool, on_setpoint=self._on_setpoint,
                                     read_value=self._read_value,
                                     on_connection=self._on_connection)
        self.network = self.implement.network
        self.port = self.implement.port
        self.client = self.implement.client
        db = iso11783_7_database()
        self._speed_messages = {
            PGN_GROUND_BASED_SPEED: ("ground", db.get_message_by_name("GroundBasedSpeedDist"),
                                     "GroundBasedMachineSpeed"),
            PGN_WHEEL_BASED_SPEED: ("wheel", db.get_message_by_name("WheelBasedSpeedDist"),
                                    "WheelBasedMachineSpeed")}
        for pgn in self._speed_messages:
            self.port.subscribe(pgn, self._on_speed)
        #: the controller's clock: the time of the last control step
        self.clock_s = 0.0
        #: target rate M from the TC, kg/ha (= kg/hm²)
        self.rate_kg_ha = 0.0
        #: the TC's section set-points, row 1 first (all on until the TC says otherwise)
        self.sections = [True] * self.row_count
        #: the TC's set-point work state (DDI 289), None until it sends one
        self.work_state: int | None = None
        #: source -> (time heard, speed m/s) of the TECU's valid speeds
        self.speed_heard: dict[str, tuple[float, float]] = {}
        self.setpoint = {"Mode": float(MODE_FIELD)}    # FlowController's view: field mode
        #: reconnect = never, after the TC was lost
        self._gave_up = False

    def on_start(self) -> list[can.Message]:
        """The boot-up message (and, for ``claim_first = "no"``, a working-set master message
        from the preferred address before the claim: the must-fail DUT's breach)."""
        boot = super().on_start()
        if self.isobus.claim_first == "no":
            early = make_frame(7, WORKING_SET_MASTER_PGN, int(self.isobus.address),
                               GLOBAL_ADDRESS, bytes([1]) + b"\xff" * 7)
            boot = [early, *boot]
        return boot

    # --- frames in ----------------------------------------------------------------------
    def on_frame(self, msg: can.Message) -> list[can.Message]:
        """Extended frames go to the ISOBUS network (what it answers waits for the next step);
        SYNC steps; flow module frames feed the rows; FertSetpoint is not listened to."""
        if msg.is_error_frame or msg.is_remote_frame:
            return []
        if msg.is_extended_id:
            if self._gave_up and decode_id(msg.arbitration_id).pgn == PROCESS_DATA_PGN:
                return []           # reconnect = never: deaf to the TC once it was lost
            self.implement.receive(msg, self.clock_s)
            return []
        if msg.arbitration_id == SYNC_ID:
            return self.step() if self.step_on_sync else []
        if msg.arbitration_id in self.flow_rows:
            return super().on_frame(msg)
        return []

    def _on_speed(self, msg: Received) -> None:
        source, message, signal = self._speed_messages[msg.pgn]
        if len(msg.data) != 8:
            return
        speed = float(message.decode(msg.data)[signal])
        if 0.0 <= speed <= MAX_VALID_SPEED_MPS:      # above: "not available" / error
            self.speed_heard[source] = (msg.time_s, speed)

    # --- what the TC sets and reads -----------------------------------------------------
    def _on_setpoint(self, element: int, ddi: int, value: int, time_s: float,
                     ) -> AckError | None:
        if element != self.elements.boom:
            return AckError.DDI_NOT_SUPPORTED_BY_ELEMENT
        if ddi == dd.SETPOINT_MASS_PER_AREA_RATE:
            rate = value / MG_PER_M2_PER_KG_HA
            if not 0.0 <= rate <= MAX_RATE_KG_HA:
                return AckError.VALUE_OUT_OF_OPERATIONAL_RANGE
            self.rate_kg_ha = self.isobus.fixed_rate_kg_ha or rate
        elif ddi == dd.SETPOINT_CONDENSED_WORK_STATE_1_16:
            states = dd.unpack_condensed_work_state(value)[:self.row_count]
            if self.isobus.sections == "tc":
                self.sections = [s == 1 for s in states]
            elif self.isobus.sections == "latch-off":
                self.sections = [s == 1 and on for s, on in zip(states, self.sections,
                                                                 strict=True)]
        elif ddi == dd.SETPOINT_WORK_STATE:
            if value not in (0, 1, 2, 3):
                return AckError.VALUE_DOES_NOT_CONFORM_TO_DDI
            self.work_state = value
        else:
            return AckError.DDI_NOT_SUPPORTED_BY_ELEMENT
        self._switch_rows()
        return None

    def _read_value(self, element: int, ddi: int, time_s: float) -> int | None:
        if element != self.elements.boom:
            return None
        metering = self.metering()
        if ddi == dd.ACTUAL_MASS_PER_AREA_RATE:
            return round(self.actual_rate_kg_ha() * MG_PER_M2_PER_KG_HA)
        if ddi == dd.SETPOINT_MASS_PER_AREA_RATE:
            return round(self.rate_kg_ha * MG_PER_M2_PER_KG_HA)
        if ddi == dd.ACTUAL_WORK_STATE:
            return 1 if metering else 0
        if ddi == dd.ACTUAL_CONDENSED_WORK_STATE_1_16:
            return dd.pack_condensed_work_state([1 if metering and on else 0
                                                 for on in self.sections])
        if ddi == dd.SETPOINT_CONDENSED_WORK_STATE_1_16:
            return dd.pack_condensed_work_state([1 if on else 0 for on in self.sections])
        if ddi == dd.SETPOINT_WORK_STATE:
            return self.work_state
        return None

    def _on_connection(self, connected: bool, time_s: float) -> None:
        if not connected and self.isobus.reconnect == "never":
            self._gave_up = True
        # a new connection starts from nothing: the TC sends its set-points again
        self.rate_kg_ha = 0.0
        self.work_state = None
        self.sections = [True] * self.row_count
        self._switch_rows()

    def _switch_rows(self) -> None:
        self.rows.switch({i + 1 for i, on in enumerate(self.sections) if on})

    # --- the control inputs -------------------------------------------------------------
    def ground_speed(self) -> tuple[str, float] | None:
        """(source, m/s) of the speed in use at the controller's clock; ``None``: lost."""
        order = ("ground", "wheel") if self.isobus.speed == "ground" else ("wheel",)
        for source in order:
            heard = self.speed_heard.get(source)
            if heard is not None and \
                    self.clock_s - heard[0] <= self.isobus.speed_timeout_s + 1e-9:
                return source, heard[1]
        return None

    def metering(self) -> bool:
        """The pool is active, a rate is set, the boom is not stopped, a row is on and a speed
        is known (``without_tc_rate_kg_ha``: without an active pool, a speed is enough)."""
        if not self.client.connected and self.isobus.without_tc_rate_kg_ha > 0.0:
            return self.ground_speed() is not None
        return (self.client.connected and self.rate_kg_ha > 0.0
                and self.work_state in (None, 1) and any(self.sections)
                and self.ground_speed() is not None)

    def target_rate_kg_ha(self) -> float:
        """The rate metered now: the TC's (or the fixed one); without a TC, the fallback."""
        if not self.client.connected and self.isobus.without_tc_rate_kg_ha > 0.0:
            return self.isobus.without_tc_rate_kg_ha
        return self.rate_kg_ha

    @property
    def enabled(self) -> bool:
        return self.metering()

    @property
    def terminal_mode(self) -> int:
        return MODE_FIELD

    def active_rows(self) -> int:
        return sum(self.sections)

    def target_gps(self) -> float:
        """Per-row target, 0.1·M·D_active·v / ActiveRows (eq. 1), 0 when not metering."""
        speed = self.ground_speed()
        if speed is None or not self.metering():
            return 0.0
        rows = self.active_rows()
        return 0.1 * self.target_rate_kg_ha() * (rows * self.row_width_m) * speed[1] / rows

    def actual_rate_kg_ha(self) -> float:
        """The measured flow of the active rows as a rate: M = Q / (0.1·D_active·v)."""
        speed = self.ground_speed()
        m = self.rows.last
        rows = self.active_rows()
        if speed is None or speed[1] < MIN_REPORT_SPEED_MPS or not m.has_measurement \
                or rows == 0 or not self.metering():
            return 0.0
        return max(0.0, m.measured_gps * rows / (0.1 * rows * self.row_width_m * speed[1]))

    # --- the control step ---------------------------------------------------------------
    def step(self) -> list[can.Message]:
        """Send what the network answered since the last step and what is due at this step's
        time, then run the law; the analog command stays the step's last frame."""
        self.clock_s = self.steps * self.adapter_params.period_s
        return self.implement.take(self.clock_s) + super().step()
