"""[F]'s flow controller as a controller that was not written for agrihil: its own database.

The bus layer of a commercial fertilizer controller, the Nordfeld RateMaster RC-400 of
``docs/examples/byo-fertilizer/ratemaster_rc400.dbc`` (a fictional layout: node 0x12, other
ids, big-endian signals, rates in kg/h, one multiplexed frame for all rows, status enums, a
500 ms status): it knows that database and its own signal names (:class:`SignalMap`), nothing
of agrihil's DBC. Every frame is decoded and encoded through cantools; values are converted
from the database's units to the control law's (g/s, m/s, m, kg/ha) by the units the database
declares. The control law is the unchanged core of
:mod:`reference_controllers.fertilizer.piecewise_pid`, with the same parameters, row validity
(:mod:`reference_controllers.fertilizer.rows`) and step order as
:class:`reference_controllers.fertilizer.adapter.FlowController`.

The rig reaches it through a binding (``ratemaster_rc400.binding.toml`` beside the database):
the rig speaks the RC-400's frames, not the other way round.
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import cantools

from hil.dut import Controller
from reference_controllers.fertilizer.piecewise_pid import OpenLoop, PiecewisePid
from reference_controllers.fertilizer.rows import FlowRows
from reference_controllers.fertilizer.speeds import GroundSpeedFirst, valid_speed
from reference_controllers.params import ParamError, ParamValue

__all__ = ["RC400_DATABASE", "RC400_SIGNALS", "DbcFlowController", "SignalMap", "rc400"]

ROOT = Path(__file__).resolve().parents[2]
RC400_DATABASE = ROOT / "docs" / "examples" / "byo-fertilizer" / "ratemaster_rc400.dbc"
SYNC_ID = 0x080                        # CANopen SYNC: one control step each in lockstep
SDO_RX = 0x600                         # CiA 301 SDO request to node n: 0x600 + n
BOOT_UP, OPERATIONAL = 0, 5            # CiA 301 heartbeat states
#: the control law's units, and each database unit's factor to them (value_law = value · f)
TO_LAW_UNITS: dict[str, tuple[str, float]] = {
    "g/s": ("g/s", 1.0), "kg/h": ("g/s", 1.0 / 3.6), "m/s": ("m/s", 1.0),
    "km/h": ("m/s", 1.0 / 3.6), "m": ("m", 1.0), "mm": ("m", 0.001), "cm": ("m", 0.01),
    "kg/ha": ("kg/ha", 1.0), "kg/hm2": ("kg/ha", 1.0), "V": ("V", 1.0), "mV": ("V", 0.001),
}
LAW_MODES = ("field", "bench", "constant")


@dataclass(frozen=True)
class SignalMap:
    """The controller's own names: which message and signal of its database means what.

    Message-qualified names are ``"Message.Signal"``; ``{row}`` in a row signal stands for
    the row (from 1); ``row_mux_values`` is the multiplexer's value of row 1, 2, ...
    Enumerations are matched by the database's value names.
    """

    target_rate: str
    working_width: str
    target_flow: str
    program: str
    run: str
    speed_source: str
    sections: str
    row_message: str
    row_multiplexer: str
    row_mux_values: tuple[int, ...]
    row_flow: str
    row_state: str
    row_diag: str
    hall_speed: str
    wheel_based_speed: str
    ground_based_speed: str
    command: str
    heartbeat: str
    status: str
    status_signals: Mapping[str, str]
    #: program value name → ``field``, ``bench`` or ``constant``
    programs: Mapping[str, str]
    #: speed source value name → ``hall``, ``wheel`` or ``ground``
    speed_sources: Mapping[str, str]
    row_ready_state: str
    row_overrange_diag: str
    status_every: int = 5
    #: the drive module's CANopen node: configured at boot to watch this controller's heartbeat
    drive_node: int = 0x20
    #: its consumer heartbeat time (0x1016 sub 1), ms
    drive_consumer_ms: int = 300
    loop_names: tuple[str, ...] = field(default=("Idle", "Fine", "Medium", "Coarse"))


#: the RC-400's names in ratemaster_rc400.dbc
RC400_SIGNALS = SignalMap(
    target_rate="RC_Command.RateKgHa", working_width="RC_Command.WidthMm",
    target_flow="RC_Command.TargetKgH", program="RC_Command.Program", run="RC_Command.Run",
    speed_source="RC_Command.SpeedSrc", sections="RC_Command.Sections",
    row_message="RH_RowFlow", row_multiplexer="RowNo", row_mux_values=(0, 1, 2, 3),
    row_flow="FlowKgH_{row}", row_state="State_{row}", row_diag="Diag_{row}",
    hall_speed="WS_GroundSpeed.SpeedKmh",
    wheel_based_speed="WheelBasedSpeedDist.WheelBasedMachineSpeed",
    ground_based_speed="GroundBasedSpeedDist.GroundBasedMachineSpeed",
    command="DriveCommand.SpeedRef", heartbeat="RC_Heartbeat.NmtState", status="RC_Status",
    status_signals={"target": "TargetKgH", "measured": "ActualKgH", "command": "DriveMv",
                    "loop": "Loop", "program": "ProgramActive", "running": "Running",
                    "alarm": "FlowAlarm", "counter": "Seq"},
    programs={"SpeedRelated": "field", "FixedRate": "bench", "FixedSpeed": "constant"},
    speed_sources={"WheelSensor": "hall", "TractorWheel": "wheel", "Radar": "ground"},
    row_ready_state="Measuring", row_overrange_diag="CapOverrange")


def _split(name: str) -> tuple[str, str]:
    message, _, signal = name.partition(".")
    return message, signal


def _pgn(frame_id: int) -> int:
    """The J1939 PGN of a 29-bit id (PDU1: the destination byte is not part of it)."""
    pgn = (frame_id >> 8) & 0x3FFFF
    return pgn & 0x3FF00 if (pgn >> 8) & 0xFF < 240 else pgn


class DbcFlowController(Controller):
    """The reference flow law behind a bus layer generated from another database.

    Parameters
    ----------
    database : str or Path
        The controller's CAN database (anything cantools reads).
    signals : SignalMap
        Its own message and signal names.
    params : mapping, optional
        The law's parameters, as :class:`~reference_controllers.fertilizer.adapter.FlowController`
        takes them (``mode``, ``ff_coeff``, ``stale_after_s`` ...).
    step_on_sync : bool
        One control step per SYNC (lockstep); False: only :meth:`on_tick` steps.

    Raises
    ------
    KeyError
        A name of ``signals`` that the database does not have.
    """

    def __init__(self, database: str | Path, signals: SignalMap,
                 params: Mapping[str, ParamValue] | None = None, *,
                 step_on_sync: bool = True) -> None:
        from reference_controllers.fertilizer.adapter import resolve_params

        self.law, self.core_params, self.adapter_params = resolve_params(None, params)
        self.name = f"fertilizer-piecewise-pid-{self.law} ({Path(database).stem})"
        self.map = signals
        self.step_on_sync = step_on_sync
        self.db = cantools.database.load_file(str(database))
        self.open_loop = OpenLoop(self.core_params)
        self.closed_loop = None if self.law == "open-loop" else PiecewisePid(self.core_params)
        self.rows = FlowRows(self.adapter_params.stale_after_s, self.adapter_params.period_s)
        self.setpoint: dict[str, Any] = {}
        self.speeds = {"hall": 0.0, "wheel": 0.0, "ground": 0.0}
        self.ground_first = GroundSpeedFirst(self.adapter_params.ground_speed_first_s,
                                             self.adapter_params.period_s)
        self.steps = 0
        self.active_mode: str | None = None
        self.volts = 0.0
        self.segment = 0
        m = signals
        self._command = _split(m.command)
        self._heartbeat = _split(m.heartbeat)
        self._status = self.db.get_message_by_name(m.status)
        self._setpoint_msg = _split(m.target_flow)[0]
        self._speed_of = {_split(m.hall_speed)[0]: ("hall", _split(m.hall_speed)[1]),
                          _split(m.wheel_based_speed)[0]: ("wheel",
                                                           _split(m.wheel_based_speed)[1]),
                          _split(m.ground_based_speed)[0]: ("ground",
                                                            _split(m.ground_based_speed)[1])}
        self._by_id: dict[int, Any] = {}
        self._by_pgn: dict[int, Any] = {}
        for name in (self._setpoint_msg, m.row_message, *self._speed_of):
            msg = self.db.get_message_by_name(name)
            if msg.is_extended_frame:
                self._by_pgn[_pgn(msg.frame_id)] = msg
            else:
                self._by_id[msg.frame_id] = msg
        self._units = {sig: self._law_factor(name) for name, sig in (
            (m.target_flow, "target_flow"), (m.target_rate, "target_rate"),
            (m.working_width, "working_width"))}
        row_msg = self.db.get_message_by_name(m.row_message)
        self._row_factor = self._law_factor(
            f"{m.row_message}.{m.row_flow.replace('{row}', '1')}", row_msg)
        self._status_factor = self._law_factor(
            f"{m.status}.{m.status_signals['target']}")

    def _law_factor(self, name: str, message: Any = None) -> float:
        msg_name, sig_name = _split(name)
        sig = (message or self.db.get_message_by_name(msg_name)).get_signal_by_name(sig_name)
        unit = sig.unit or ""
        if unit not in TO_LAW_UNITS:
            raise KeyError(f"{name}: unit {unit!r} is not one this controller converts "
                           f"({', '.join(TO_LAW_UNITS)})")
        return TO_LAW_UNITS[unit][1]

    # --- frames in ----------------------------------------------------------------------
    def on_start(self) -> list[can.Message]:
        """Boot-up, then configure the drive module as CANopen masters do: its consumer
        heartbeat (0x1016 sub 1) watches this node, so it stops the motor when we go silent."""
        return [self._encode(*self._heartbeat, BOOT_UP), self._consumer_heartbeat_sdo()]

    def _consumer_heartbeat_sdo(self) -> can.Message:
        node = self.db.get_message_by_name(self._heartbeat[0]).frame_id - 0x700
        value = (node << 16) | self.map.drive_consumer_ms
        data = bytes([0x23, 0x16, 0x10, 0x01]) + value.to_bytes(4, "little")  # expedited, 4 B
        return can.Message(arbitration_id=SDO_RX + self.map.drive_node, is_extended_id=False,
                           data=data)

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.is_error_frame or msg.is_remote_frame:
            return []
        if not msg.is_extended_id and msg.arbitration_id == SYNC_ID:
            return self.step() if self.step_on_sync else []
        message = (self._by_pgn.get(_pgn(msg.arbitration_id)) if msg.is_extended_id
                   else self._by_id.get(msg.arbitration_id))
        if message is None:
            return []
        with contextlib.suppress(cantools.database.DecodeError, ValueError, KeyError):
            self._take(message, message.decode(bytes(msg.data), decode_choices=True))
        return []

    def _take(self, message: Any, values: Mapping[str, Any]) -> None:
        m = self.map
        if message.name == self._setpoint_msg:
            self.setpoint = dict(values)
        elif message.name == m.row_message:
            index = m.row_mux_values.index(int(values[m.row_multiplexer]))
            row = index + 1
            flow = float(values[m.row_flow.replace("{row}", str(row))]) * self._row_factor
            state = str(values[m.row_state.replace("{row}", str(row))])
            diag = str(values[m.row_diag.replace("{row}", str(row))])
            self.rows.report(row, flow, state == m.row_ready_state,
                             diag == m.row_overrange_diag, self.steps)
        elif message.name in self._speed_of:
            source, signal = self._speed_of[message.name]
            speed = float(values[signal]) * self._law_factor(f"{message.name}.{signal}")
            self.speeds[source] = speed if valid_speed(speed) else 0.0
            if source == "ground":
                self.ground_first.heard(speed, self.steps)

    # --- the control step -----------------------------------------------------------------
    def _value(self, name: str) -> Any:
        return self.setpoint.get(_split(name)[1])

    @property
    def enabled(self) -> bool:
        return bool(self.setpoint) and int(self._value(self.map.run)) == 1

    @property
    def program(self) -> str:
        """``field``, ``bench`` or ``constant`` (bench before any set-point, as the reference)."""
        if not self.setpoint:
            return "bench"
        return self.map.programs.get(str(self._value(self.map.program)), "bench")

    def target_gps(self) -> float:
        """Target flow per row: the fixed rate, or 0.1·M·D·v / sections in the field."""
        if not self.enabled:
            return 0.0
        if self.program == "field":
            source = self.map.speed_sources.get(str(self._value(self.map.speed_source)))
            speed = self.ground_first.field_speed(self.speeds, source, self.steps)
            rows = max(1, int(self._value(self.map.sections)))
            rate = float(self._value(self.map.target_rate)) * self._units["target_rate"]
            width = float(self._value(self.map.working_width)) * self._units["working_width"]
            return 0.1 * rate * width * speed / rows
        return float(self._value(self.map.target_flow)) * self._units["target_flow"]

    def active_rows(self) -> int | None:
        """The rows that meter: 1..Sections once a command has come (the others' clutches
        are out and their modules read a stopped roller's 0 g/s), all before one, as the
        reference counts rows 1..ActiveRows."""
        if not self.setpoint:
            return None
        return max(1, int(self._value(self.map.sections)))

    def on_tick(self) -> list[can.Message]:
        """One free-running control step (a daemon's timer, not SYNC)."""
        return self.step()

    def step(self) -> list[can.Message]:
        """Run the law once; the status (every ``status_every`` steps), heartbeat, command."""
        target = self.target_gps()
        mode = self.program
        if mode != self.active_mode:
            if self.closed_loop is not None:
                self.closed_loop.reset()
            self.active_mode = mode
        m = self.rows.measure(target, self.steps, self.active_rows())
        law = self.open_loop if (mode == "constant" or self.closed_loop is None) \
            else self.closed_loop
        self.volts, self.segment = law.step(target, m.measured_gps, m.has_measurement,
                                            m.new_report)
        out: list[can.Message] = []
        if self.steps % self.map.status_every == 0:
            out.append(self._status_frame(target, m.measured_gps if m.has_measurement else 0.0,
                                          law is self.closed_loop and self.enabled
                                          and not m.has_measurement))
        out.append(self._encode(*self._heartbeat, OPERATIONAL))
        out.append(self._encode(*self._command, round(self.volts * 1000.0)))
        self.steps += 1
        return out

    def _status_frame(self, target: float, measured: float, alarm: bool) -> can.Message:
        s = self.map.status_signals
        program = {v: k for k, v in self.map.programs.items()}[self.program]
        limit = self._status.get_signal_by_name(s["target"]).maximum / self._status_factor
        values = {s["target"]: min(max(target, 0.0), limit) / self._status_factor,
                  s["measured"]: min(measured, limit) / self._status_factor,
                  s["command"]: round(self.volts * 1000.0),
                  s["loop"]: self.map.loop_names[self.segment],
                  s["program"]: program, s["running"]: int(self.enabled),
                  s["alarm"]: int(alarm), s["counter"]: self.steps % 256}
        return can.Message(arbitration_id=self._status.frame_id,
                           is_extended_id=self._status.is_extended_frame,
                           data=self._status.encode(values))

    def _encode(self, message: str, signal: str, value: Any) -> can.Message:
        msg = self.db.get_message_by_name(message)
        return can.Message(arbitration_id=msg.frame_id, is_extended_id=msg.is_extended_frame,
                           data=msg.encode({signal: value}))


def rc400(**params: ParamValue) -> Controller:
    """The RC-400 build of the reference controller, for a profile's ``launch.inprocess``.

    Raises
    ------
    ValueError
        An unknown parameter name or a bad value (named).
    """
    try:
        return DbcFlowController(RC400_DATABASE, RC400_SIGNALS, params)
    except ParamError as exc:
        raise ValueError(str(exc)) from exc
