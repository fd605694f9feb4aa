"""[D]'s depth controller on CAN: the CiA 402 drive's master running the fuzzy PID.

Section 2, "CAN adapter", of ``docs/reference-controllers.md``. Plain frames go through the
rig's DBC (:class:`FrameCodec`), the drive's PDOs through canopen PDO maps read from its EDS
(a :class:`canopen.RemoteNode` on an :class:`OutboxNetwork`, no bus of its own); the PDOs of
every step (TPDO1/2 in, RPDO2 out) are packed and unpacked by one ``struct`` laid out from
those maps (:mod:`.pdo_struct`, checked against canopen), the rest by canopen itself.

* on the drive's heartbeat 0x702 showing anything but Operational: NMT start ``[0x01, 2]``;
* once Operational: Modes of operation = 3 (profile velocity) through RPDO3, once (again
  after the drive drops out of Operational);
* each step (SYNC, or :meth:`on_tick` when free-running): RPDO2 (Controlword, Target velocity
  in 0.01 mm/s) with the controlword of :mod:`.cia402_master` and the fuzzy PID's speed;
* every 10th step (the first included): DepthControllerStatus and the heartbeat 0x701.

Depth: the inclinometer's X voltage with status "ok", eq. 13 ``depth = -0.065·x + 270.35``,
filtered ``d += 0.2·(depth - d)`` per frame (the first frame sets d). The depth is invalid
(the PID resets and the roller is held, see below; the status frame says SensorFault) while
the status is not "ok", and while the X voltage has not changed for more than
``frozen_after_s``: a live inclinometer never repeats one ADC count for 0.2 s, 20 reports (its
noise alone is ~1.7 counts SD at standstill, 2-5 on a moving machine), so a frozen output or
one that stopped sending is a dead sensor, not a steady depth. Enabled: the terminal says on +
automatic and a ground speed >= ``min_speed_mps`` is known (GBSD or GNSS, see
:mod:`.ground_speed`).

Where the roller is held (:mod:`.roller_hold`): while the depth is valid and control enabled,
the adapter tracks the mean rod position (TPDO1's Position actual value 0x6064, tau = 2 s),
and takes it as the hold target at each new X voltage (the sensor's last sign of life); when
the depth turns invalid while control stays enabled (and the drive is in Operation enabled)
it drives the rod back to that target, ``speed = clamp(5/s·(h - p), ±10 mm/s)``, and holds
it there; the status frame carries the target as RollerPositionCommand (0 otherwise).
Control disabled forgets mean and target and commands 0 (the roller stays where it is).
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import can
import canopen
from canopen.pdo.base import PdoMap

from hil.dut import Controller
from hil.errors import FrameError
from hil.rig.canopen_device import OutboxNetwork, object_dictionary
from plant_emulators.sowing_depth.config import SowingDepthRigConfig, load_rig_config
from plant_emulators.sowing_depth.frames import (
    EDS_PATH,
    ControllerStatus,
    DepthSetpoint,
    Frame,
    FrameCodec,
    GroundSpeed,
    InclinometerFrame,
)
from plant_emulators.sowing_depth.sensors import calibration_depth_mm
from reference_controllers.params import ParamError, ParamValue, field_names, override, split
from reference_controllers.sowing_depth.cia402_master import (
    MODE_PROFILE_VELOCITY,
    is_fault,
    is_operation_enabled,
    next_controlword,
)
from reference_controllers.sowing_depth.fuzzy_pid import FuzzyPid, FuzzyPidParams
from reference_controllers.sowing_depth.ground_speed import NmeaPort, SpeedSources
from reference_controllers.sowing_depth.pdo_struct import PdoStruct
from reference_controllers.sowing_depth.roller_hold import RollerHold, RollerHoldParams

SYNC_ID = 0x080
NMT_OPERATIONAL = 0x05
CONTROLLER_NODE_ID = 1
DEPTH_FILTER = 0.2
STATUS_EVERY = 10
#: J1939 "not available" speeds decode above the signal's valid maximum
MAX_VALID_SPEED_MPS = 64.255
GNSS_PORT_ENV = "AGRIHIL_GNSS_PORT"


@dataclass(frozen=True)
class DepthAdapterParams:
    """The adapter's own parameters: when a ground speed counts as known, when an
    unchanging inclinometer counts as dead (``frozen_after_s``; 0 turns the check off), and
    where the roller is held while the depth is invalid (``hold_*``: the fields of
    :class:`~reference_controllers.sowing_depth.roller_hold.RollerHoldParams`, whose
    docstring says why these values)."""

    min_speed_mps: float = 0.1
    speed_timeout_s: float = 1.0
    #: 20 reports of 10 ms with one X voltage. The LVT525H's own noise (0.02 deg, 20 ms
    #: low-pass) is ~1.7 mV at 83 mV/deg, so two consecutive reports repeat a whole-mV value
    #: with p ~ 0.27 at standstill: 20 repeats (p ~ 2e-12) only a frozen output gives. Every
    #: 10 ms the frozen depth is trusted moves the roller (up to 50 mm/s): 0.5 s left the
    #: depth up to ~2.2 mm off for the rest of a stuck fault (issue #16)
    frozen_after_s: float = 0.2
    hold_time_constant_s: float = RollerHoldParams.time_constant_s
    hold_gain_per_s: float = RollerHoldParams.gain_per_s
    hold_speed_mm_s: float = RollerHoldParams.speed_mm_s

    def __post_init__(self) -> None:
        self.hold()

    def hold(self) -> RollerHoldParams:
        """The hold's parameters (raises ``ValueError`` naming one out of range)."""
        return RollerHoldParams(self.hold_time_constant_s, self.hold_gain_per_s,
                                self.hold_speed_mm_s)


def resolve_params(params: Mapping[str, ParamValue] | None) -> tuple[FuzzyPidParams,
                                                                     DepthAdapterParams]:
    """(core parameters, adapter parameters) from ``key=value`` pairs; unknown keys raise
    :class:`~reference_controllers.params.ParamError` naming the key."""
    adapter_values, core_values = split(dict(params or {}), field_names(DepthAdapterParams))
    core = override(FuzzyPidParams(), core_values)
    adapter = override(DepthAdapterParams(), adapter_values)
    if not adapter.hold_speed_mm_s <= core.v_max:
        raise ParamError("hold_speed_mm_s must be <= v_max, got "
                         f"{adapter.hold_speed_mm_s} > {core.v_max}")
    return core, adapter


#: the DBC signals the controller reads, by the typed frames' own field-to-signal maps
_INC_X_MV = InclinometerFrame.SIGNALS["x_mv"]
_INC_X_STATUS = InclinometerFrame.SIGNALS["x_status"]
_DS_TARGET = DepthSetpoint.SIGNALS["target_depth_mm"]
_DS_ENABLE = DepthSetpoint.SIGNALS["enable"]
_DS_MODE = DepthSetpoint.SIGNALS["mode"]
_GBSD_SPEED = GroundSpeed.SIGNALS["speed_mps"]
#: the TPDO and RPDO2 variables the controller uses, by canopen's names (the EDS's)
TPDO1_FIELDS = ("Statusword", "Position actual value")
TPDO2_FIELDS = ("Statusword",)
RPDO2_FIELDS = ("Controlword", "Target velocity")


def _fields(pdo: PdoMap, names: tuple[str, ...]) -> tuple[PdoStruct, tuple[int, ...]] | None:
    """The struct of a TPDO map and where ``names`` sit in it; None if it has none or lacks
    one of them (canopen's path then reads the frame, and raises on the missing name)."""
    layout = PdoStruct.build(pdo)
    if layout is None or not set(names) <= set(layout.names):
        return None
    return layout, tuple(layout.names.index(name) for name in names)


class DepthController(Controller):
    """The reference depth controller of [D] as an in-process controller.

    Parameters
    ----------
    params : mapping, optional
        Overrides of :class:`FuzzyPidParams` (presets ``kp0``, ``ki0``, ``kd0`` …) and of
        :class:`DepthAdapterParams`.
    step_on_sync : bool
        Run a control step on each SYNC (lockstep); False: only :meth:`on_tick` steps.
    **more_params
        More parameters as keywords (how ``hil`` hands a profile's ``[parameters]`` to a
        ``launch.inprocess`` class); unknown names raise
        :class:`~reference_controllers.params.ParamError` naming them.
    """

    name = "sowing-depth-fuzzy-pid"

    def __init__(self, params: Mapping[str, ParamValue] | None = None, *,
                 step_on_sync: bool = True, rig_config: SowingDepthRigConfig | None = None,
                 **more_params: ParamValue) -> None:
        self.core_params, self.adapter_params = resolve_params({**(params or {}),
                                                                **more_params})
        self.core = FuzzyPid(self.core_params)
        self.hold = RollerHold(self.adapter_params.hold())
        self.step_on_sync = step_on_sync
        wiring = (rig_config or load_rig_config()).wiring
        self.node_id = wiring.drive_node_id
        self.codec = FrameCodec()
        self.network = OutboxNetwork()
        self.drive = canopen.RemoteNode(self.node_id, object_dictionary(EDS_PATH, self.node_id))
        self.network.add_node(self.drive)
        self.drive.rpdo.read(from_od=True)
        self.drive.tpdo.read(from_od=True)
        #: TPDO1/2 (statusword; TPDO1 the position too) and RPDO2 (controlword, target
        #: velocity) as structs laid out from canopen's maps (.pdo_struct: one struct call per
        #: frame instead of canopen's per-variable path); None where canopen reads them
        self._tpdo_structs = {pdo: _fields(self.drive.tpdo[pdo], fields)
                              for pdo, fields in ((1, TPDO1_FIELDS), (2, TPDO2_FIELDS))}
        command = PdoStruct.build(self.drive.rpdo[2])
        self._command = (command if command is not None and command.names == RPDO2_FIELDS
                         else None)
        self.ids = {"incl": wiring.inclinometer_frame_id,
                    "setpoint": wiring.depth_setpoint_frame_id,
                    "speed": wiring.ground_speed_frame_id}
        self.speeds = SpeedSources(self.adapter_params.speed_timeout_s)
        self.gnss: NmeaPort | None = None
        self.drive_nmt: int | None = None
        self.statusword = 0
        #: Position actual value 0x6064 from TPDO1 (0.01 mm increments / 100), None before any
        self.position_mm: float | None = None
        self.holding = False
        self.last_controlword = 0
        self.mode_sent = False
        self.target_mm = 30.0
        self.terminal_on = False
        self.automatic = False
        self.manual = False
        self.depth_mm: float | None = None
        self.depth_ok = False
        self.last_x_mv: float | None = None
        self.x_changed_at_s = 0.0
        self.steps = 0
        self.speed_mm_s = 0.0
        self.gains = (self.core_params.kp0, self.core_params.ki0, self.core_params.kd0)

    # --- set-up ---------------------------------------------------------------------------
    def configure(self, env: dict[str, str]) -> None:
        """Open the GNSS serial port the rig names in ``AGRIHIL_GNSS_PORT``, if any."""
        path = env.get(GNSS_PORT_ENV)
        if path and self.gnss is None:
            self.gnss = NmeaPort(path)

    def on_start(self) -> list[can.Message]:
        return [can.Message(arbitration_id=0x700 + CONTROLLER_NODE_ID, data=b"\x00",
                            is_extended_id=False)]

    def close(self) -> None:
        if self.gnss is not None:
            self.gnss.close()

    @property
    def now_s(self) -> float:
        return self.steps * self.core_params.period_s

    # --- frames in ----------------------------------------------------------------------------
    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.is_error_frame or msg.is_remote_frame:
            return []
        can_id = msg.arbitration_id
        if msg.is_extended_id:
            with contextlib.suppress(FrameError):   # an undecodable frame is ignored
                self._take_plain(msg)
            return []
        if can_id == SYNC_ID:
            return self.step() if self.step_on_sync else []
        if can_id == 0x700 + self.node_id and msg.dlc >= 1:
            self.drive_nmt = msg.data[0] & 0x7F
            if self.drive_nmt != NMT_OPERATIONAL:
                self.mode_sent = False
                self.drive.nmt.send_command(0x01)     # NMT start [0x01, node]
                return self.network.take()
        elif can_id in (0x180 + self.node_id, 0x280 + self.node_id):
            pdo = 1 if can_id == 0x180 + self.node_id else 2
            fields = self._tpdo_structs[pdo]
            values = None if fields is None else fields[0].unpack(msg.data)
            if values is not None:
                self.statusword = values[fields[1][0]]
                if pdo == 1:
                    self.position_mm = values[fields[1][1]] / 100.0
                return []
            # canopen's own path: a map without a struct layout, a frame shorter than its map
            self.network.notify(can_id, bytes(msg.data), msg.timestamp)
            self.statusword = int(self.drive.tpdo[pdo]["Statusword"].raw)
            if pdo == 1:
                self.position_mm = int(self.drive.tpdo[1]["Position actual value"].raw) / 100.0
        return []

    def _take_plain(self, msg: can.Message) -> None:
        can_id = msg.arbitration_id
        if can_id == self.ids["incl"]:
            values = self._signals(msg, InclinometerFrame)
            x_mv = values[_INC_X_MV]
            self.depth_ok = values[_INC_X_STATUS] == "ok"
            if self.depth_ok:
                if x_mv != self.last_x_mv:
                    self.last_x_mv, self.x_changed_at_s = x_mv, self.now_s
                    self.hold.mark()         # a sign of life: the mean so far is trusted
                depth = calibration_depth_mm(x_mv)
                self.depth_mm = depth if self.depth_mm is None else (
                    self.depth_mm + DEPTH_FILTER * (depth - self.depth_mm))
        elif can_id == self.ids["setpoint"]:
            values = self._signals(msg, DepthSetpoint)
            self.target_mm = float(values[_DS_TARGET])
            self.terminal_on = values[_DS_ENABLE] == "on"
            self.automatic = values[_DS_MODE] == "automatic"
            self.manual = values[_DS_MODE] == "manual"
        elif can_id == self.ids["speed"]:
            value = float(self._signals(msg, GroundSpeed)[_GBSD_SPEED])
            self.speeds.update("gbsd", value if 0.0 <= value <= MAX_VALID_SPEED_MPS else None,
                               self.now_s)

    def _signals(self, msg: can.Message, cls: type[Frame]) -> dict[str, Any]:
        """The signal values (by DBC name) of a frame that must be a ``cls``.

        What :meth:`FrameCodec.decode` gives as a ``cls`` frame, without building the frozen
        dataclass (~90,000 frames a depth campaign sample); a frame of another name goes
        through ``decode`` itself, which raises as it always did.
        """
        name, values = self.codec.decode_signals(msg)
        if name != cls.FRAME:
            frame = self.codec.decode(msg)           # FrameError: no typed codec
            assert isinstance(frame, cls)
        return values

    # --- the control step -----------------------------------------------------------------
    def on_tick(self) -> list[can.Message]:
        """One free-running control step (a daemon's timer, not SYNC)."""
        return self.step()

    def frozen(self) -> bool:
        """The inclinometer's X voltage has not changed for more than ``frozen_after_s``."""
        limit = self.adapter_params.frozen_after_s
        return (limit > 0.0 and self.last_x_mv is not None
                and self.now_s - self.x_changed_at_s > limit + 1e-9)

    def enabled(self) -> bool:
        speed = self.speeds.speed(self.now_s)
        return (self.terminal_on and self.automatic and speed is not None
                and speed >= self.adapter_params.min_speed_mps)

    def step(self) -> list[can.Message]:
        """Run the fuzzy PID once and return the frames of this step."""
        if self.gnss is not None:
            for value in self.gnss.poll():
                self.speeds.update("gnss", value, self.now_s)
        if self.drive_nmt == NMT_OPERATIONAL and not self.mode_sent:
            self.drive.rpdo[3]["Modes of operation"].raw = MODE_PROFILE_VELOCITY
            self.drive.rpdo[3].transmit()
            self.mode_sent = True
        controlword = next_controlword(self.statusword, self.last_controlword)
        self.last_controlword = controlword
        frozen = self.frozen()
        valid = (self.depth_mm is not None and self.depth_ok and not frozen
                 and is_operation_enabled(self.statusword))
        enabled = self.enabled()
        speed, kp, ki, kd = self.core.step(self.target_mm, self.depth_mm or 0.0, valid,
                                           enabled)
        # where the roller is held (.roller_hold): track the mean rod position while
        # regulating, drive the rod back to it while the depth is invalid on a running
        # machine, forget it when control is switched off (the core commands 0: it stays)
        self.holding = False
        if enabled and valid:
            if self.position_mm is not None:
                self.hold.track(self.position_mm, self.core_params.period_s)
        elif not enabled:
            self.hold.reset()
        elif (is_operation_enabled(self.statusword) and self.position_mm is not None
              and self.hold.target_mm is not None):
            self.holding = True
            speed = self.hold.speed(self.position_mm)
        self.speed_mm_s, self.gains = speed, (kp, ki, kd)
        velocity = round(speed * 100.0)
        layout = self._command
        payload = None if layout is None else layout.pack_values((controlword, velocity))
        if payload is not None:
            out = self.network.take()
            command = can.Message(arbitration_id=layout.cob_id, data=payload,
                                  is_extended_id=layout.cob_id > 0x7FF)
        else:                        # canopen's own path (it raises on a value out of range)
            self.drive.rpdo[2]["Controlword"].raw = controlword
            self.drive.rpdo[2]["Target velocity"].raw = velocity
            self.drive.rpdo[2].transmit()
            out = self.network.take()
            command = out.pop()          # RPDO2, transmitted last above
        if self.steps % STATUS_EVERY == 0:
            out.append(self._status(valid and enabled, frozen))
            out.append(can.Message(arbitration_id=0x700 + CONTROLLER_NODE_ID,
                                   data=bytes([NMT_OPERATIONAL]), is_extended_id=False))
        # the command frame goes last: in lockstep it closes the step (the rig's SYNC barrier
        # waits for it), so the status and heartbeat must be on the bus before it
        out.append(command)
        self.steps += 1
        return out

    def _status(self, controlling: bool, frozen: bool) -> can.Message:
        if is_fault(self.statusword):
            state = "fault"
        elif self.manual:
            state = "manual"
        elif controlling:
            state = "controlling"
        elif is_operation_enabled(self.statusword):
            state = "ready"
        else:
            state = "initialising"
        depth = 0.0 if self.depth_mm is None else min(max(self.depth_mm, -100.0), 200.0)
        # holding: the hold target in whole 0.01 mm (half to even, as the C build); regulating
        # in profile velocity mode there is no position command: 0
        command = 0.0
        if self.holding and self.hold.target_mm is not None:
            command = round(min(max(self.hold.target_mm, 0.0), 100.0) * 100.0) / 100.0
        return self.codec.encode(ControllerStatus(
            measured_depth_mm=round(depth, 1), roller_position_command_mm=command, state=state,
            sensor_fault=int(self.depth_mm is None or not self.depth_ok or frozen),
            drive_fault=int(is_fault(self.statusword)),
            speed_lost=int(self.speeds.speed(self.now_s) is None),
            counter=(self.steps // STATUS_EVERY) % 16))
