"""[D]'s depth controller as an ISOBUS implement: the seeding depth from a Task Controller
(variable-depth seeding, issue 42).

The control law and the drive side are those of
:class:`~reference_controllers.sowing_depth.adapter.DepthController` (the same fuzzy PID, roller
hold, CiA 402 master, inclinometer and GNSS serial line); only where the target depth comes from
changes. Instead of agrihil's DepthSetpoint frame (ignored here) the controller hosts an
implement control function on its own :class:`~hil.isobus.network.IsobusNetwork`:

* **NAME** industry group 2, device class 4 (planters/seeders), function 128,
  self-configurable, preferred address 0x82 (parameter ``address``);
* **DDOP** (:func:`depth_pool`): the device and one function element, the seed line, with its
  working width (DDI 67), offsets from the device reference point (134/135: the seed tubes
  1.9 m behind it), its set-point latency (142), the set-point seeding depth (56, settable),
  the actual seeding depth (57, on change and every second) and the default, minimum and
  maximum seeding depth (58, 59, 60) as ISO 11783-11 defines them;
* a :class:`~hil.isobus.tc_client.TaskControllerClient` connects to the TC; DDI 56 (mm) is the
  target depth; a value outside 59-60 is refused (process data acknowledge, value out of
  operational range);
* **the TC lost** (no status for 6 s, a restart, a refused pool): the target falls back to the
  default seeding depth the DDOP declares (DDI 58), which is what the device descriptor says
  the implement does without a set-point; the fuzzy PID keeps regulating there. A new
  connection starts from the default until the TC sends its depth.

The actual depth reported (DDI 57) is the controller's sensed depth (eq. 13, filtered), in whole
mm as the DDI's resolution is. Speed is the GNSS receiver's on the serial line, as in the
terminal mode (the rig's path drives it and the TECU alike). Time: as the fertilizer's ISOBUS
mode, the network never reads a clock; it runs on the control step count.

Must-fail parameters (each a defect a real implement could have; defaults are the reference):
``fixed_depth_mm`` > 0 holds that depth whatever the TC sends (ignores the map);
``actual = "setpoint"`` reports the set-point as the actual depth; ``fallback = "hold"`` keeps
the last set-point when the TC is lost instead of the declared default.
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
from hil.isobus.process_data import AckError
from plant_emulators.sowing_depth.config import SowingDepthRigConfig, load_rig_config
from reference_controllers.isobus_implement import TcImplement, check_address
from reference_controllers.isobus_implement import implement_name as shared_implement_name
from reference_controllers.params import ParamError, ParamValue, field_names, override, split
from reference_controllers.sowing_depth.adapter import DepthController

__all__ = ["DepthElements", "IsobusDepthController", "IsobusDepthParams", "depth_pool"]

SEEDER_FUNCTION = 128
"""ISO 11783-1 function 128 (device-class dependent) of device class 4, planters/seeders."""
DEVICE_CLASS_PLANTERS = 4

_ON_CHANGE_OR_TIME = TriggerMethod.ON_CHANGE | TriggerMethod.TIME_INTERVAL
#: the source address of the terminal mode's DepthControllerStatus in the rig's DBC
STATUS_SOURCE = 0x80


@dataclass(frozen=True)
class IsobusDepthParams:
    """The ISOBUS side's parameters (a DUT profile's ``[parameters]`` may set each).

    ``default_depth_mm``, ``min_depth_mm``, ``max_depth_mm``: DDI 58-60 of the DDOP (the
    terminal mode's 30 mm working depth of [D]; the rig's 10-60 mm of roller travel as the
    range); ``latency_ms``: DDI 142, what the TC leads the map by ([D]'s ~1.1 s response, the
    roller's 50 mm/s over a 10 mm change and the controller's step). The rest: see the module.
    """

    address: float = 0x82
    identity_number: float = 0x0D42
    default_depth_mm: float = 30.0
    min_depth_mm: float = 10.0
    max_depth_mm: float = 60.0
    latency_ms: float = 1000.0
    fixed_depth_mm: float = 0.0
    actual: str = "sensed"
    fallback: str = "default"

    def __post_init__(self) -> None:
        check_address(self.address, self.identity_number)
        if not (0.0 < self.min_depth_mm <= self.default_depth_mm <= self.max_depth_mm <= 100.0):
            raise ValueError(f"need 0 < min_depth_mm <= default_depth_mm <= max_depth_mm <= "
                             f"100, got {self.min_depth_mm}, {self.default_depth_mm}, "
                             f"{self.max_depth_mm}")
        if not (math.isfinite(self.latency_ms) and 0.0 <= self.latency_ms <= 10000.0):
            raise ValueError(f"latency_ms must be within [0, 10000], got {self.latency_ms}")
        if not (self.fixed_depth_mm == 0.0
                or self.min_depth_mm <= self.fixed_depth_mm <= self.max_depth_mm):
            raise ValueError(f"fixed_depth_mm must be 0 or within the depth range, got "
                             f"{self.fixed_depth_mm}")
        if self.actual not in ("sensed", "setpoint"):
            raise ValueError(f"actual must be sensed or setpoint, got {self.actual!r}")
        if self.fallback not in ("default", "hold"):
            raise ValueError(f"fallback must be default or hold, got {self.fallback!r}")


@dataclass(frozen=True)
class DepthElements:
    """Element number of the DDOP's seed line."""

    seed_line: int


def depth_pool(*, name: int, width_m: float, offset_x_mm: int, params: IsobusDepthParams,
               ) -> tuple[ObjectPool, DepthElements]:
    """The depth controller's device descriptor object pool and its seed line's element."""
    b = PoolBuilder(version=4)
    dvc = b.device("agrihil depth seeder", software_version="1.0.0", name=name,
                   serial_number="1", structure_label=b"AGD-ISO")
    mm = b.presentation("mm")
    ms = b.presentation("ms")
    device = b.element(ElementType.DEVICE, "Depth seeder", parent=dvc)
    line = b.element(ElementType.FUNCTION, "Seed line", parent=device)
    b.property(line, ddi=dd.ACTUAL_WORKING_WIDTH, value=round(width_m * 1000),
               designator="Working width", presentation=mm)
    b.property(line, ddi=dd.DEVICE_ELEMENT_OFFSET_X, value=offset_x_mm, designator="Offset X",
               presentation=mm)
    b.property(line, ddi=dd.DEVICE_ELEMENT_OFFSET_Y, value=0, designator="Offset Y",
               presentation=mm)
    b.property(line, ddi=dd.PHYSICAL_SETPOINT_TIME_LATENCY, value=round(params.latency_ms),
               designator="Setpoint latency", presentation=ms)
    b.property(line, ddi=dd.DEFAULT_SEEDING_DEPTH, value=round(params.default_depth_mm),
               designator="Default depth", presentation=mm)
    b.property(line, ddi=dd.MINIMUM_SEEDING_DEPTH, value=round(params.min_depth_mm),
               designator="Minimum depth", presentation=mm)
    b.property(line, ddi=dd.MAXIMUM_SEEDING_DEPTH, value=round(params.max_depth_mm),
               designator="Maximum depth", presentation=mm)
    b.process_data(line, ddi=dd.SETPOINT_SEEDING_DEPTH, designator="Target depth",
                   settable=True, presentation=mm)
    b.process_data(line, ddi=dd.ACTUAL_SEEDING_DEPTH, designator="Actual depth",
                   triggers=_ON_CHANGE_OR_TIME, presentation=mm)
    pool = b.build(validate=True)
    number = {e.object_id: e.element_number for e in pool.elements}
    return pool, DepthElements(number[line])


def implement_name(identity_number: int) -> IsobusName:
    """The controller's NAME: agriculture, planters/seeders, self-configurable."""
    return shared_implement_name(identity_number, device_class=DEVICE_CLASS_PLANTERS,
                                 function=SEEDER_FUNCTION)


class IsobusDepthController(DepthController):
    """The reference depth controller as an ISOBUS implement (TC client, depth DDOP).

    Raises
    ------
    ParamError
        An unknown parameter or a bad value, named.
    """

    name = "sowing-depth-fuzzy-pid-isobus"

    def __init__(self, params: Mapping[str, ParamValue] | None = None, *,
                 step_on_sync: bool = True, rig_config: SowingDepthRigConfig | None = None,
                 **more_params: ParamValue) -> None:
        mine, rest = split({**(params or {}), **more_params}, field_names(IsobusDepthParams))
        try:
            self.isobus = override(IsobusDepthParams(), mine)
        except ValueError as exc:
            raise ParamError(str(exc)) from exc
        config = rig_config or load_rig_config()
        super().__init__(rest, step_on_sync=step_on_sync, rig_config=config)
        machine = config.machine
        self.implement_name = implement_name(int(self.isobus.identity_number))
        self.pool, self.elements = depth_pool(
            name=self.implement_name.value,
            width_m=machine.rows * machine.row_spacing_mm / 1000.0,
            offset_x_mm=-round(machine.tractor_rear_axle_ahead_of_seed_m * 1000),
            params=self.isobus)
        # the CANopen side's OutboxNetwork is self.network: the ISOBUS one is the implement's
        self.implement = TcImplement(network_name=self.name, name=self.implement_name,
                                     address=int(self.isobus.address), label="depth seeder",
                                     pool=self.pool, on_setpoint=self._on_setpoint,
                                     read_value=self._read_value,
                                     on_connection=self._on_connection)
        self.port = self.implement.port
        self.client = self.implement.client
        #: the TC's depth (mm), None until it sends one on this connection
        self.tc_depth_mm: float | None = None
        # the implement works automatically: the TC's depth, else the declared default
        self.terminal_on = True
        self.automatic = True
        self.target_mm = self.isobus.default_depth_mm

    # --- frames in ----------------------------------------------------------------------
    def on_frame(self, msg: can.Message) -> list[can.Message]:
        """Extended frames go to the ISOBUS network (what it answers waits for the next step)
        and, but for DepthSetpoint, to the terminal mode's handling as well (the rig's
        inclinometer node speaks 29-bit frames); the rest as the terminal mode takes them."""
        if msg.is_error_frame or msg.is_remote_frame:
            return []
        if msg.is_extended_id:
            self.implement.receive(msg, self.now_s)
            if msg.arbitration_id == self.ids["setpoint"]:
                return []
        return super().on_frame(msg)

    # --- what the TC sets and reads -----------------------------------------------------
    def _on_setpoint(self, element: int, ddi: int, value: int, time_s: float,
                     ) -> AckError | None:
        if element != self.elements.seed_line or ddi != dd.SETPOINT_SEEDING_DEPTH:
            return AckError.DDI_NOT_SUPPORTED_BY_ELEMENT
        if not self.isobus.min_depth_mm <= value <= self.isobus.max_depth_mm:
            return AckError.VALUE_OUT_OF_OPERATIONAL_RANGE
        self.tc_depth_mm = float(value)
        return None

    def _read_value(self, element: int, ddi: int, time_s: float) -> int | None:
        if element != self.elements.seed_line:
            return None
        if ddi == dd.SETPOINT_SEEDING_DEPTH:
            return round(self.target_mm)
        if ddi == dd.ACTUAL_SEEDING_DEPTH:
            if self.isobus.actual == "setpoint":
                return round(self.target_mm)
            return round(self.depth_mm) if self.depth_mm is not None and self.depth_ok else 0
        return None

    def _on_connection(self, connected: bool, time_s: float) -> None:
        # lost, or a new connection: no set-point until the TC sends one, the default meanwhile
        # (fallback = "hold": the last one heard stays, the must-fail's defect)
        if self.isobus.fallback == "default":
            self.tc_depth_mm = None

    def current_target_mm(self) -> float:
        """The depth to hold now: the fixed one (a must-fail), the TC's while the pool is
        active and it sent one, else the declared default (or, ``fallback = "hold"``, the
        last set-point heard)."""
        if self.isobus.fixed_depth_mm > 0.0:
            return self.isobus.fixed_depth_mm
        if self.tc_depth_mm is not None and (self.client.connected
                                             or self.isobus.fallback == "hold"):
            return self.tc_depth_mm
        return self.isobus.default_depth_mm

    # --- the control step ---------------------------------------------------------------
    def step(self) -> list[can.Message]:
        """What the network answered since the last step and what is due now, then the law
        (the drive's command stays the step's last frame)."""
        isobus = self.implement.take(self.now_s)
        self.target_mm = self.current_target_mm()
        own = [self._own(m) for m in super().step()]
        return isobus + [m for m in own if m is not None]

    def _own(self, msg: can.Message) -> can.Message | None:
        """The terminal mode's 29-bit status (DepthControllerStatus, from 0x80 in the rig's
        DBC, the address an ISOBUS TECU takes) from the address this implement claimed, and
        none before the claim (ISO 11783-5: nothing but the claim before it)."""
        if not msg.is_extended_id:
            return msg
        frame = decode_id(msg.arbitration_id)
        if frame.source != STATUS_SOURCE:
            return msg
        address = self.port.address
        if address is None:
            return None
        return make_frame(frame.priority, frame.pgn, address, frame.destination,
                          bytes(msg.data))
