"""[D]'s depth controller as a controller that was not written for agrihil: its own database.

The bus layer of a commercial sowing depth controller, the Feldtakt DepthPro DP-200 of
``docs/examples/byo-depth/depthpro_dp200.dbc`` (a fictional layout: CANopen node 0x0A, 11-bit
ids, big-endian frames, depths in cm, roller travel in µm, one multiplexed sensor hub frame for
the inclinometer and the draw-wire sensor, status enums with its own numbers, a 200 ms status
and a 500 ms heartbeat). It knows that database and its own signal names
(:class:`DepthSignalMap`), nothing of agrihil's DBC. Every frame is decoded and encoded through
cantools; values are converted from the database's units to the law's (mm, mV, m/s, mm/s) by
the units the database declares, and rounded to the signal's resolution, as the reference's
own codec rounds.

As a CANopen master it configures its drive at boot, as masters do (:mod:`.drive_config`): on
the drive's boot-up it sends the SDO writes that remap the drive's PDOs to the DP-200's frames
(``DP_DriveCommand``: RPDO1 at 0x302, Target velocity then Controlword, synchronous;
``DP_DriveFeedback``: TPDO1 at 0x1A2, Position actual value, Statusword, Modes of operation
display, every SYNC; ``DP_DriveDiagnosis``: TPDO3 at 0x2A2, Error code and Current actual
value, event-driven every 100 ms with a 10 ms inhibit time; every other PDO invalid) and set
the heartbeat producer time; its next control step starts the drive (NMT start) once every
write is confirmed. It configures the drive again whenever the drive boots or reports anything
but Operational (a reset restores the EDS defaults); a drive it finds Operational after its
own power cycle keeps the configuration it gave it before. Profile velocity mode (0x6060 = 3)
is selected by SDO on the first step with the drive Operational, once per start of the drive:
none of its PDOs maps the mode. A refused write leaves the drive stopped and the status in
Fault (:attr:`DbcDepthController.config_error` says which object and code). Every frame it
sends is either an answer to the drive's boot-up or part of a control step, as lockstep asks.

The control law, its parameters and its step order are the reference's
(:class:`reference_controllers.sowing_depth.depth_law.DepthLaw`, the rules of
:class:`reference_controllers.sowing_depth.adapter.DepthController`): the fuzzy PID, the
frozen-inclinometer check, the roller hold, the ground speed sources (GBSD and the GNSS port).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import cantools

from hil.dut import Controller
from reference_controllers.params import ParamError, ParamValue
from reference_controllers.sowing_depth.cia402_master import MODE_PROFILE_VELOCITY
from reference_controllers.sowing_depth.depth_law import DepthLaw, LawStep
from reference_controllers.sowing_depth.drive_config import (
    PdoConfig,
    SdoBatch,
    check_against_database,
    configuration_writes,
)

__all__ = ["DP200_DATABASE", "DP200_DRIVE_PDOS", "DP200_SIGNALS", "DbcDepthController",
           "DepthSignalMap", "dp200"]

ROOT = Path(__file__).resolve().parents[2]
DP200_DATABASE = ROOT / "docs" / "examples" / "byo-depth" / "depthpro_dp200.dbc"
SYNC_ID = 0x080
BOOT_UP, OPERATIONAL = 0, 5                # CiA 301 heartbeat states
NMT_START = 0x01
#: the law's units, and each database unit's factor to them (value_law = value · f)
TO_LAW_UNITS: dict[str, tuple[str, float]] = {
    "mm": ("mm", 1.0), "cm": ("mm", 10.0), "um": ("mm", 0.001), "m": ("mm", 1000.0),
    "mV": ("mV", 1.0), "V": ("mV", 1000.0), "m/s": ("m/s", 1.0), "km/h": ("m/s", 1.0 / 3.6),
    "mm/s": ("mm/s", 1.0), "": ("", 1.0),
}


@dataclass(frozen=True)
class DepthSignalMap:
    """The controller's own names: which message and signal of its database means what.

    Names are ``"Message.Signal"``; enumerations are matched by the database's value names.
    """

    target_depth: str
    enable: str
    mode: str
    sensor_message: str
    sensor_multiplexer: str
    inclinometer_channel: str
    inclinometer_x: str
    inclinometer_x_state: str
    ground_speed: str
    status: str
    status_signals: Mapping[str, str]
    heartbeat: str
    nmt: str
    drive_heartbeat: str
    drive_sdo_request: str
    drive_sdo_response: str
    drive_command: str
    drive_feedback: str
    drive_diagnosis: str
    #: the value names: enable on, automatic mode, a valid inclinometer output
    enable_on: str
    mode_automatic: str
    mode_manual: str
    inclinometer_valid: str
    #: the law's state → the status enum's value name
    states: Mapping[str, str]
    status_every: int = 20
    heartbeat_every: int = 50
    #: the drive's heartbeat producer time the master writes (0x1017), ms
    drive_heartbeat_ms: int = 100
    drive_pdos: tuple[PdoConfig, ...] = field(default=())


#: the drive's PDOs as the DP-200 maps them (the frames of its database)
DP200_DRIVE_PDOS = (
    PdoConfig("rpdo", 1, "DP_DriveCommand", ((0x60FF, 0, 32), (0x6040, 0, 16)), 1),
    PdoConfig("tpdo", 1, "DP_DriveFeedback", ((0x6064, 0, 32), (0x6041, 0, 16),
                                              (0x6061, 0, 8)), 1),
    PdoConfig("tpdo", 3, "DP_DriveDiagnosis", ((0x603F, 0, 16), (0x6078, 0, 16)), 255,
              event_timer_ms=100, inhibit_100us=100),
)

#: the DP-200's names in depthpro_dp200.dbc
DP200_SIGNALS = DepthSignalMap(
    target_depth="DP_Setpoint.TargetDepth", enable="DP_Setpoint.Enable",
    mode="DP_Setpoint.Mode", sensor_message="DP_SensorHub", sensor_multiplexer="Channel",
    inclinometer_channel="ArmInclinometer", inclinometer_x="ArmTiltX",
    inclinometer_x_state="TiltXState", ground_speed="GBSD.GroundBasedMachineSpeed",
    status="DP_Status",
    status_signals={"depth": "DepthCm", "roller": "RollerCmd", "state": "State",
                    "sensor_fault": "SensorFault", "drive_fault": "DriveFault",
                    "speed_lost": "NoSpeed", "counter": "Seq", "drive_error": "DriveError"},
    heartbeat="DP_Heartbeat.NmtState", nmt="DP_Nmt", drive_heartbeat="DP_DriveHeartbeat.NmtState",
    drive_sdo_request="DP_DriveSdoRequest", drive_sdo_response="DP_DriveSdoResponse",
    drive_command="DP_DriveCommand", drive_feedback="DP_DriveFeedback",
    drive_diagnosis="DP_DriveDiagnosis", enable_on="On", mode_automatic="AutoDepth",
    mode_manual="Manual", inclinometer_valid="Valid",
    states={"initialising": "Init", "ready": "Standby", "controlling": "Regulating",
            "manual": "Manual", "fault": "Fault"},
    drive_pdos=DP200_DRIVE_PDOS)


def _split(name: str) -> tuple[str, str]:
    message, _, signal = name.partition(".")
    return message, signal


def _decimals(step: float) -> int:
    """Decimal places that represent every multiple of ``step`` (0.001 → 3, 10 → 0)."""
    for places in range(10):
        if abs(round(step, places) - step) < 1e-12 * max(1.0, step):
            return places
    return 10


class _Reader:
    """One signal's value in the law's unit, rounded to the signal's resolution there."""

    def __init__(self, message: Any, signal: str) -> None:
        sig = message.get_signal_by_name(signal)
        unit = sig.unit or ""
        if unit not in TO_LAW_UNITS:
            raise KeyError(f"{message.name}.{signal}: unit {unit!r} is not one this "
                           f"controller converts ({', '.join(u for u in TO_LAW_UNITS if u)})")
        self.signal = signal
        self.factor = TO_LAW_UNITS[unit][1]
        self.places = _decimals(abs(sig.scale))
        self.law_places = _decimals(abs(sig.scale) * self.factor)

    def __call__(self, values: Mapping[str, Any]) -> float:
        value = round(float(values[self.signal]), self.places)
        return value if self.factor == 1.0 else round(value * self.factor, self.law_places)


def _raw(sig: Any, value: float) -> int:
    """The raw count of ``value`` (in the signal's unit): ``value`` times the counts per unit
    when that is a whole number (0.01 mm/s: 100 per mm/s), as the reference computes it."""
    per_unit = 1.0 / sig.scale
    if abs(per_unit - round(per_unit)) < 1e-9:
        return round(value * round(per_unit))
    return round(value / sig.scale)


class DbcDepthController(Controller):
    """The reference depth law behind a bus layer generated from another database.

    Parameters
    ----------
    database : str or Path
        The controller's CAN database (anything cantools reads).
    signals : DepthSignalMap
        Its own message and signal names, and the drive's PDOs it configures.
    params : mapping, optional
        The law's parameters, as
        :class:`~reference_controllers.sowing_depth.adapter.DepthController` takes them.
    step_on_sync : bool
        One control step per SYNC (lockstep); False: only :meth:`on_tick` steps.

    Raises
    ------
    KeyError
        A name of ``signals`` that the database does not have, or a unit it cannot convert.
    ValueError
        A drive frame of the database that is not what its PDO mapping makes.
    """

    def __init__(self, database: str | Path, signals: DepthSignalMap,
                 params: Mapping[str, ParamValue] | None = None, *,
                 step_on_sync: bool = True) -> None:
        self.law = DepthLaw(params)
        self.name = f"sowing-depth-fuzzy-pid ({Path(database).stem})"
        self.map = m = signals
        self.step_on_sync = step_on_sync
        self.db = cantools.database.load_file(str(database))
        msg = self.db.get_message_by_name
        self._setpoint = msg(_split(m.target_depth)[0])
        self._sensors = msg(m.sensor_message)
        self._speed = msg(_split(m.ground_speed)[0])
        self._status = msg(m.status)
        self._command = msg(m.drive_command)
        self._feedback = msg(m.drive_feedback)
        self._diagnosis = msg(m.drive_diagnosis)
        self._drive_heartbeat = msg(_split(m.drive_heartbeat)[0])
        self._sdo_request = msg(m.drive_sdo_request)
        self._sdo_response = msg(m.drive_sdo_response)
        self._target = _Reader(self._setpoint, _split(m.target_depth)[1])
        self._incl_x = _Reader(self._sensors, m.inclinometer_x)
        self._ground = _Reader(self._speed, _split(m.ground_speed)[1])
        self._position = _Reader(self._feedback, "PositionActual")
        self.drive_node = self._drive_heartbeat.frame_id - 0x700
        self.node_id = msg(_split(m.heartbeat)[0]).frame_id - 0x700
        cob_ids = check_against_database(m.drive_pdos, self.db)
        self.configuration = configuration_writes(
            m.drive_pdos, cob_ids, self.drive_node,
            application=((0x1017, 0, m.drive_heartbeat_ms, 2),))
        self._by_id = {(x.frame_id, bool(x.is_extended_frame)): x for x in (
            self._setpoint, self._sensors, self._speed, self._feedback, self._diagnosis,
            self._drive_heartbeat, self._sdo_response)}
        self.sdo: SdoBatch | None = None
        #: the mode write (0x6060), once per start of the drive
        self.mode_sdo: SdoBatch | None = None
        self.configured = False
        self.config_error: str | None = None
        self.drive_nmt: int | None = None
        #: the drive's last error code (0x603F), from its diagnosis PDO
        self.drive_error = 0

    # --- set-up ---------------------------------------------------------------------------
    def configure(self, env: dict[str, str]) -> None:
        """Open the GNSS serial port the rig names in ``AGRIHIL_GNSS_PORT``, if any."""
        self.law.configure(env)

    def close(self) -> None:
        self.law.close()

    def on_start(self) -> list[can.Message]:
        return [self._encode(*_split(self.map.heartbeat), BOOT_UP)]

    # --- frames in ----------------------------------------------------------------------
    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.is_error_frame or msg.is_remote_frame:
            return []
        if not msg.is_extended_id and msg.arbitration_id == SYNC_ID:
            return self.step() if self.step_on_sync else []
        message = self._by_id.get((msg.arbitration_id, bool(msg.is_extended_id)))
        if message is None:
            return []
        with contextlib.suppress(cantools.database.DecodeError, ValueError, KeyError):
            return self._take(message, bytes(msg.data))
        return []

    def _take(self, message: Any, data: bytes) -> list[can.Message]:
        m = self.map
        if message is self._sdo_response:
            return self._on_sdo_response(data)
        if message is self._drive_heartbeat:
            state = message.decode(data, decode_choices=False)[_split(m.drive_heartbeat)[1]]
            return self._on_drive_heartbeat(int(state) & 0x7F)
        values = message.decode(data, decode_choices=True)
        if message is self._sensors:
            if str(values[m.sensor_multiplexer]) == m.inclinometer_channel:
                ok = str(values[m.inclinometer_x_state]) == m.inclinometer_valid
                self.law.inclinometer(ok, self._incl_x(values) if ok else 0.0)
        elif message is self._setpoint:
            mode = str(values[_split(m.mode)[1]])
            self.law.set_job(self._target(values),
                             str(values[_split(m.enable)[1]]) == m.enable_on,
                             mode == m.mode_automatic, mode == m.mode_manual)
        elif message is self._speed:
            self.law.ground_speed(self._ground(values))
        elif message is self._feedback:
            self.law.drive_feedback(int(values["Statusword"]), self._position(values))
        elif message is self._diagnosis:
            self.drive_error = int(values["ErrorCode"])
        return []

    # --- the drive's configuration (CANopen master) -------------------------------------------
    def _on_drive_heartbeat(self, state: int) -> list[can.Message]:
        """Configure the drive when it booted or is not Operational (it is started by the
        next step once every write is confirmed).

        A drive found Operational without our configuration (after our own power cycle) is
        taken as configured: only its boot (power-up, NMT reset) restores its EDS defaults,
        and then it reports boot-up and is configured again.
        """
        self.drive_nmt = state
        pending = self.sdo is not None and self.sdo.pending
        if state != OPERATIONAL:
            self.mode_sdo = None      # selected again once the drive is started
        if self.config_error is not None and state != BOOT_UP:
            return []                 # refused: the drive stays stopped until it reboots
        if state == BOOT_UP or (state != OPERATIONAL and not pending):
            self.configured, self.config_error = False, None
            self.sdo = SdoBatch(self._sdo_request, self._sdo_response, self.configuration)
            return self.sdo.frames()
        if state == OPERATIONAL and not pending:
            self.configured = True
        return []

    def _on_sdo_response(self, data: bytes) -> list[can.Message]:
        batch = self.sdo if self.sdo is not None and self.sdo.pending else self.mode_sdo
        if batch is not None:
            batch.on_response(data)
            self.config_error = self.config_error or batch.error
        return []

    def _drive_management(self) -> list[can.Message]:
        """This step's frames to the drive ahead of its command: the NMT start once the
        configuration is confirmed, then (once the drive reports Operational) the mode."""
        if self.config_error is not None:
            return []
        if self.sdo is not None and self.sdo.done and not self.configured:
            self.configured = True
            if self.drive_nmt != OPERATIONAL:
                nmt = self.db.get_message_by_name(self.map.nmt)
                return [can.Message(arbitration_id=nmt.frame_id, is_extended_id=False,
                                    data=nmt.encode({"Command": NMT_START,
                                                     "Node": self.drive_node}))]
        if self.configured and self.drive_nmt == OPERATIONAL and self.mode_sdo is None:
            # profile velocity, once per start of the drive: no PDO of ours maps 0x6060
            self.mode_sdo = SdoBatch(self._sdo_request, self._sdo_response,
                                     [(0x6060, 0, MODE_PROFILE_VELOCITY, 1)])
            return self.mode_sdo.frames()
        return []

    # --- the control step -----------------------------------------------------------------
    def on_tick(self) -> list[can.Message]:
        """One free-running control step (a daemon's timer, not SYNC)."""
        return self.step()

    def step(self) -> list[can.Message]:
        """Run the law once; the status and heartbeat when due, the drive command last."""
        out = self._drive_management()
        step = self.law.step()
        steps = self.law.steps
        if steps % self.map.status_every == 0:
            out.append(self._status_frame(step))
        if steps % self.map.heartbeat_every == 0:
            out.append(self._encode(*_split(self.map.heartbeat), OPERATIONAL))
        # the command goes last: in lockstep it closes the step
        out.append(self._drive_command(step.speed_mm_s, step.controlword))
        self.law.end_step()
        return out

    def _drive_command(self, speed_mm_s: float, controlword: int) -> can.Message:
        velocity = self._command.get_signal_by_name("TargetVelocity")
        data = self._command.encode({"TargetVelocity": _raw(velocity, speed_mm_s),
                                     "Controlword": controlword}, scaling=False)
        return can.Message(arbitration_id=self._command.frame_id, is_extended_id=False,
                           data=data)

    def state(self, step: LawStep) -> str:
        """The law's state (a refused configuration is a fault)."""
        return "fault" if self.config_error is not None else self.law.status(step).state

    def _status_frame(self, step: LawStep) -> can.Message:
        s = self.map.status_signals
        status = self.law.status(step)
        depth_sig = self._status.get_signal_by_name(s["depth"])
        roller_sig = self._status.get_signal_by_name(s["roller"])
        values = {s["depth"]: status.measured_depth_mm / TO_LAW_UNITS[depth_sig.unit][1],
                  s["roller"]: status.roller_position_command_mm
                  / TO_LAW_UNITS[roller_sig.unit][1],
                  s["state"]: self.map.states[self.state(step)],
                  s["sensor_fault"]: int(status.sensor_fault),
                  s["drive_fault"]: int(status.drive_fault),
                  s["speed_lost"]: int(status.speed_lost),
                  s["counter"]: (self.law.steps // self.map.status_every) % 16,
                  s["drive_error"]: self.drive_error}
        raw = {name: self._raw_value(name, value) for name, value in values.items()}
        return can.Message(arbitration_id=self._status.frame_id,
                           is_extended_id=self._status.is_extended_frame,
                           data=self._status.encode(raw, scaling=False))

    def _raw_value(self, signal: str, value: Any) -> int:
        sig = self._status.get_signal_by_name(signal)
        if isinstance(value, str):
            return next(int(raw) for raw, name in sig.choices.items() if str(name) == value)
        if sig.scale == 1 and sig.offset == 0:
            return int(value)
        return _raw(sig, value) if math.isfinite(value) else 0

    def _encode(self, message: str, signal: str, value: Any) -> can.Message:
        msg = self.db.get_message_by_name(message)
        return can.Message(arbitration_id=msg.frame_id, is_extended_id=msg.is_extended_frame,
                           data=msg.encode({signal: value}))


def dp200(**params: ParamValue) -> Controller:
    """The DP-200 build of the reference depth controller, for a profile's
    ``launch.inprocess``.

    Raises
    ------
    ValueError
        An unknown parameter name or a bad value (named).
    """
    try:
        return DbcDepthController(DP200_DATABASE, DP200_SIGNALS, params)
    except ParamError as exc:
        raise ValueError(str(exc)) from exc
