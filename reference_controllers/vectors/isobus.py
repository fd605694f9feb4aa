"""Shared vectors of the fertilizer controller's ISOBUS mode: every frame in and out, per call.

``python -m reference_controllers.vectors.isobus`` runs
:class:`~reference_controllers.fertilizer.isobus_mode.IsobusFlowController` against the
emulated tractor (TECU + Task Controller, :class:`hil.isobus.tractor.Tractor`) on a
:class:`~hil.isobus.wire.VirtualWire`, as ``tests/reference_controllers/test_refctl_isobus.py``
does: a SYNC every 100 ms and an ideal meter (each active row reports the last per-row target
on its flow module frame before the SYNC). It records each frame handed to the controller and
the frames the controller answered with, in order, so that the C firmware
(``firmware/isobus/``) can be fed the same frames and held to the same answers byte for byte
(the ``isobus_vectors`` ctest).

File format (one file per scenario, ``isobus-*.frames``), candump-like::

    # comment
    #params law=physical speed=ground ...
    > 710#00                 a frame the controller sent (boot-up: before any input)
    < 18FFFF80#0011...       a frame handed to the controller
    > 0CCB8081#...           what it answered, in order, up to the next '<'

Identifiers of 8 hex digits are extended (29-bit), of 3 standard (11-bit); data in hex.

Scenarios:

* ``isobus-drive``: the example field (three passes over the three-zone map, headland turns,
  an overlapping fourth pass where two rows switch off), with a TC restart of 8 s (the 6 s
  status timeout, reconnection from the stored pool's labels), a TC restart of 1 s (noticed
  from the TC's NACK), the TECU's speed frames lost for 2 s, and a dropped CTS of the pool
  transfer (the sender's T3 timeout and abort, the client's transfer timeout, a new attempt);
* ``isobus-refused``: a DDOP the TC refuses (``ddop=broken``);
* ``isobus-contention``: another NAME takes the controller's address (it moves to the next
  free self-configurable address and the TC learns of it), requests for the address claim,
  a defended claim, the wheel-based speed variant, non-default parameters;
* ``isobus-scripted-tc``: a scripted TC (fixed frames at fixed times, not the emulated one)
  that goes where a well-behaved TC does not: a CTS hold, a retransmission request, a CTS
  beyond the message (abort 250), every kind of process data command with good and bad
  elements, DDIs, values and triggers, malformed frames, NACKs to others and to the
  controller, a version request timing out, no language command, an activation refused;
* ``isobus-scripted-tp``: long groups to the controller by TP and BAM, good and bad;
* ``isobus-scripted-claims``, ``-transfers``, ``-eoma``: cannot-claim, a version 3 TC, TP
  sending's hold, timeouts, retransmission limit and end-of-message acknowledgement;
* ``isobus-tc-no-memory``: a scripted TC without memory for the pool.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import can

from hil.isobus.can_id import encode_id
from hil.isobus.ddop import ObjectPool
from hil.isobus.faults import Contend, DropCts, IsobusFaults
from hil.isobus.field import load_field, load_prescription
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.wire import ScriptedNode, VirtualWire
from hil.rig.device import Device
from plant_emulators.fertilizer.frames import FertilizerDatabase
from reference_controllers.fertilizer.isobus_mode import (
    IsobusFlowController,
    implement_name,
    meter_pool,
)
from reference_controllers.vectors import VECTOR_DIR, params_line

FIELDS = Path(__file__).resolve().parents[2] / "plant_emulators" / "fertilizer" / "fields"
SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
DRIVE_AFTER_S = 3.0
SPEED_PGNS = (0xFE48, 0xFE49, 0xF022)
SUFFIX = ".frames"


def frame_text(msg: can.Message) -> str:
    """``ID#DATA`` as candump writes it (8 hex digits: extended)."""
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    return f"{ident}#{bytes(msg.data).hex().upper()}"


class RecordingNode(Device):
    """The controller on the wire (SYNC every period, an ideal meter), recording its frames."""

    def __init__(self, controller: IsobusFlowController,
                 wrong_row: tuple[int, float, float, float] | None = None) -> None:
        self.ctl = controller
        #: (row, gain, from s, to s): that row's module reads gain x the flow meanwhile
        self.wrong_row = wrong_row
        self.period_s = controller.adapter_params.period_s
        self.lines: list[str] = [f"> {frame_text(f)}" for f in controller.on_start()]
        self._last_target = 0.0
        self._db = FertilizerDatabase()

    def _feed(self, msg: can.Message) -> list[can.Message]:
        self.lines.append(f"< {frame_text(msg)}")
        out = self.ctl.on_frame(msg)
        self.lines.extend(f"> {frame_text(f)}" for f in out)
        return out

    def next_due(self, time_s: float) -> float:
        return max(self.ctl.steps * self.period_s, math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        for row in sorted(self.ctl.rows.active):
            flow = self._last_target
            if self.wrong_row is not None:
                wrong, gain, start_s, end_s = self.wrong_row
                if row == wrong and start_s <= time_s < end_s:
                    flow = round(flow * gain, 2)
            self._feed(self._db.encode(f"FlowModule{row}", {
                "Flow": flow, "WindowMass": flow, "Counter": 1,
                "BaselineReady": 1, "SlidingWindow": 1, "AdcOverrange": 0,
                "InterceptApplied": 0, "WindowLength": 1000}))
        out = self._feed(SYNC)
        self._last_target = self.ctl.target_gps()
        return out

    def accepts(self, msg: can.Message) -> bool:
        return bool(msg.is_extended_id)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        return self._feed(msg)


@dataclass(frozen=True)
class Scenario:
    """One recorded run: its parameters, what the tractor does, for how long."""

    name: str
    description: str
    params: dict[str, str | float]
    end_s: float
    slip: float = 0.0
    faults: Callable[[], IsobusFaults] = IsobusFaults
    #: (run time, action on the tractor and the wire) in time order
    actions: tuple[tuple[float, Callable[[Tractor, VirtualWire], None]], ...] = ()
    drop: Callable[[can.Message, int], bool] | None = None
    #: instead of the emulated tractor, a scripted peer: (run time, frame) to send
    script: Callable[[], list[tuple[float, can.Message]]] | None = None
    #: (row, gain, from s, to s): that row's module reads gain x the flow with good flags
    wrong_row: tuple[int, float, float, float] | None = None


def _tractor(slip: float, faults: IsobusFaults) -> Tractor:
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    return Tractor(TractorSetup(fld, rx, drive_after_s=DRIVE_AFTER_S, wheel_slip=slip),
                   faults=faults)


def record(s: Scenario) -> list[str]:
    """Run ``s`` and return the vector file's lines."""
    ctl = IsobusFlowController(str(s.params["law"]),
                               {k: v for k, v in s.params.items() if k != "law"})
    node = RecordingNode(ctl, s.wrong_row)
    if s.script is not None:
        wire = VirtualWire([ScriptedNode(s.script(), "scripted TC"), node])
        wire.run_until(s.end_s)
        return _lines(s, ctl, node)
    tractor = _tractor(s.slip, s.faults())
    wire = VirtualWire([tractor.network, node], drop=s.drop)
    for at_s, action in s.actions:
        wire.run_until(at_s)
        action(tractor, wire)
    wire.run_until(s.end_s)
    return _lines(s, ctl, node)


def _lines(s: Scenario, ctl: IsobusFlowController, node: RecordingNode) -> list[str]:
    head = [f"# {line}" for line in s.description.splitlines()]
    head.append(f"# {ctl.steps} control steps; written by python -m "
                f"reference_controllers.vectors.isobus")
    return [*head, params_line(s.params), *node.lines]


def _speed_silent(start_s: float, end_s: float) -> Callable[[can.Message, int], bool]:
    def drop(frame: can.Message, sender: int) -> bool:
        return (sender == 0 and start_s <= frame.timestamp < end_s
                and (frame.arbitration_id >> 8) & 0x3FFFF in SPEED_PGNS)
    return drop


def _restart(down_s: float) -> Callable[[Tractor, VirtualWire], None]:
    def act(tractor: Tractor, wire: VirtualWire) -> None:
        tractor.tc.restart(wire.now, down_s=down_s)
    return act


def _inject(pgn: int, source: int, destination: int, data: bytes,
            priority: int = 6) -> Callable[[Tractor, VirtualWire], None]:
    frame = can.Message(arbitration_id=encode_id(priority, pgn, source, destination),
                        data=data, is_extended_id=True)

    def act(tractor: Tractor, wire: VirtualWire) -> None:
        wire.inject(frame)
    return act


TC = 0xF7
TECU = 0x80
ME = 0x81


def _frame(priority: int, pgn: int, source: int, destination: int, hex_data: str,
           ) -> can.Message:
    return can.Message(arbitration_id=encode_id(priority, pgn, source, destination),
                       data=bytes.fromhex(hex_data.replace(" ", "")), is_extended_id=True)


def _pd(hex_data: str) -> can.Message:
    """Process data from the scripted TC to the controller."""
    return _frame(5, 0xCB00, TC, ME, hex_data)


def _element(command: int, element: int, ddi: int, value: int) -> str:
    return (bytes([command | (element & 0xF) << 4, element >> 4]) + ddi.to_bytes(2, "little")
            + (value & 0xFFFFFFFF).to_bytes(4, "little")).hex()


def _status(task_active: bool = False) -> can.Message:
    return _frame(3, 0xCB00, TC, 0xFF, f"FEFFFFFF{1 if task_active else 0:02X}0000FF")


def _cts(packets: int, next_packet: int) -> can.Message:
    return _frame(7, 0xEC00, TC, ME, f"11{packets:02X}{next_packet:02X}FFFF00CB00")


def _speed(mps: float) -> can.Message:
    raw = round(mps * 1000)
    return _frame(3, 0xFE49, TECU, 0xFF, f"{raw & 0xFF:02X}{raw >> 8:02X}0000000000FD")


def _connect_script() -> list[tuple[float, can.Message]]:
    """Status, version, language, an unknown structure label: up to the transfer request."""
    return [(0.45, _status()), (0.55, _pd("10 04 FF 15 00 01 10 00")),
            (0.55, _pd("00 FF FF FF FF FF FF FF")),
            (0.65, _frame(6, 0xFE0F, TC, 0xFF, "656E000000000000")),
            (0.75, _pd("11 FF FF FF FF FF FF FF"))]


def _scripted_tc() -> list[tuple[float, can.Message]]:
    rows_12_on = 0xFFFFFF05          # slots 0, 1 on, 2, 3 off, the rest not installed
    script = [
        *_connect_script(),
        (0.85, _pd("51 00 FF FF FF FF FF FF")),                 # transfer: go ahead
        (0.95, _cts(16, 1)), (1.05, _cts(0, 17)),                # 16 packets, then a hold
        (1.15, _cts(16, 1)), (1.25, _cts(16, 17)),               # a retransmission, on
        (1.35, _cts(255, 33)),                                   # beyond the message: abort
        (1.45, _pd("71 00 5F 03 00 00 FF FF")),                  # "transfer ok" anyway
        (1.55, _pd("91 00 FF FF FF FF 00 FF")),                  # activated
        (1.65, _pd(_element(0x3, 1, 6, 16000))),                 # 160 kg/ha, no ack
        (1.65, _pd(_element(0xA, 1, 6, 20000))),                 # 200 kg/ha, ack
        (1.75, _pd(_element(0x3, 1, 6, 200000))),                # 2000 kg/ha: out of range
        (1.75, _pd(_element(0x3, 1, 7, 5))),                     # not settable
        (1.75, _pd(_element(0x3, 9, 6, 5))),                     # no element 9
        (1.75, _pd(_element(0x3, 1, 999, 5))),                   # no such DDI
        (1.75, _pd(_element(0x3, 2, 6, 5))),                     # a section has no DDI 6
        (1.85, _pd(_element(0x3, 1, 289, 5))),                   # work state 5
        (1.85, _pd(_element(0xA, 1, 289, 1))),
        (1.85, _pd(_element(0x3, 1, 290, rows_12_on))),
        (1.95, _pd(_element(0x2, 1, 7, -1))), (1.95, _pd(_element(0x2, 1, 141, -1))),
        (1.95, _pd(_element(0x2, 1, 161, -1))), (1.95, _pd(_element(0x2, 1, 290, -1))),
        (1.95, _pd(_element(0x2, 1, 289, -1))), (1.95, _pd(_element(0x2, 1, 6, -1))),
        (1.95, _pd(_element(0x2, 1, 142, -1))),                  # a property, not a DPD
        (2.05, _pd(_element(0x2, 0, 0xDFFF, -1))),               # the default set
        (2.05, _pd(_element(0x4, 1, 7, 500))),                   # time interval 500 ms
        (2.05, _pd(_element(0x8, 1, 141, 1))),                   # on change
        (2.05, _pd(_element(0x8, 1, 6, 100))),
        (2.05, _pd(_element(0x6, 1, 7, 100))),                   # threshold: not offered
        (2.05, _pd(_element(0x5, 1, 7, 1000))),                  # distance: no source
        (2.05, _pd(_element(0x4, 1, 161, 0))),                   # a zero interval
        (2.05, _pd(_element(0x4, 1, 6, 1000))),                  # time: not offered
        (2.05, _pd(_element(0x8, 1, 161, -5))),                  # a negative threshold
        (2.05, _pd(_element(0x8, 1, 161, 1))),
        (2.15, _pd("99 00 06 00 00 00 00 00")),                  # peer control: ignored
        (2.15, _pd("03 10 06 00 00")),                           # too short: ignored
        (2.15, _pd("0D 00 06 00 00 F3 FF FF")),                  # the TC's acknowledge
        (2.15, _pd("FF FF FF FF 00 00 00 00")),                  # a client task from it
        (2.15, _pd("C1 FF FF FF FF FF FF FF")),                  # reserved sub-command
        (2.45, _status(task_active=True)),
        (3.05, _frame(6, 0xE800, TC, 0xFF, "01FFFFFF9000CB00")),  # NACK to another
        (3.15, _frame(6, 0xE800, TC, 0xFF, "01FFFFFF8100CC00")),  # NACK of another PGN
        (3.55, _frame(6, 0xE800, TC, ME, "01FFFFFF8100CB00")),    # NACK to us: restart
        (4.45, _status()),
        # the restarted attempt's version request times out (2 s): lost, waiting for status
        (6.45, _status()), (6.55, _pd("10 04 FF 15 00 01 10 00")),
        # no language command: after 2 s on without it, the structure label is asked for
        (8.45, _status()),
        (8.65, _pd("11 41 47 46 2D 49 53 4F")),                  # AGF-ISO: the known pool
        (8.75, _pd("31 65 6E 00 00 00 00 FF")),                  # en: no transfer
        (8.85, _pd("91 01 05 00 0D 00 01 FF")),                  # refused, object 13
        (8.95, _pd(_element(0x2, 1, 7, -1))),                    # ignored now
        (10.45, _status()),
    ]
    script += [(0.05 + 0.1 * k, _speed(2.0)) for k in range(10, 80)]
    return script


def _tp(source: int, destination: int, hex_data: str) -> can.Message:
    return _frame(7, 0xEC00, source, destination, hex_data)


def _dt(source: int, destination: int, hex_data: str) -> can.Message:
    return _frame(7, 0xEB00, source, destination, hex_data)


def _scripted_tp() -> list[tuple[float, can.Message]]:
    """Long groups to the controller: TP (good and bad), BAM, aborts, timeouts."""
    peer, other = 0x90, 0x91
    return [
        *_connect_script()[:4],
        # the structure label with an extended label, 15 bytes by TP, one packet per CTS
        (0.75, _tp(TC, ME, "10 0F 00 03 01 00 CB 00")),
        (0.85, _dt(TC, ME, "01 11 41 47 46 2D 49 53")),
        (0.95, _dt(TC, ME, "02 4F 45 58 54 4C 41 42")),
        (1.05, _dt(TC, ME, "03 4C")),                            # short last frame: padded
        (1.15, _pd("51 00 FF FF FF FF FF FF")),                  # transfer: go ahead
        (1.25, _cts(16, 1)),
        (1.35, _tp(TC, ME, "FF FA FF FF FF 00 CB 00")),           # the TC aborts the transfer
        (1.45, _pd("71 00 5F 03 00 00 FF FF")),
        (1.55, _pd("91 00 FF FF FF FF 00 FF")),                  # activated
        # a BAM (DM1 of 10 bytes) to everyone, heard and let go; one out of order, dropped
        (1.65, _tp(TECU, 0xFF, "20 0A 00 02 FF CA FE 00")),
        (1.72, _dt(TECU, 0xFF, "01 00 FF 00 00 00 00 FF")),
        (1.79, _dt(TECU, 0xFF, "02 FF FF FF FF FF FF FF")),
        (1.85, _tp(TECU, 0xFF, "20 0A 00 02 FF CA FE 00")),
        (1.92, _dt(TECU, 0xFF, "02 FF FF FF FF FF FF FF")),
        # bad RTSs: too short, packets not matching the size, a BAM to one address
        (2.05, _tp(peer, ME, "10 05 00 01 FF 00 CB 00")),
        (2.05, _tp(other, ME, "10 0A 00 03 FF 00 CB 00")),
        (2.05, _tp(peer, ME, "20 0A 00 02 FF 00 CB 00")),
        # out of order: abort 7; a repeat: abort 8
        (2.15, _tp(peer, ME, "10 15 00 03 FF 00 CB 00")),
        (2.25, _dt(peer, ME, "02 00 00 00 00 00 00 00")),
        (2.35, _tp(peer, ME, "10 15 00 03 02 00 CB 00")),
        (2.45, _dt(peer, ME, "01 00 00 00 00 00 00 00")),
        (2.45, _dt(peer, ME, "01 00 00 00 00 00 00 00")),
        # one packet per CTS: the next CTS goes at once after each (then T2 runs out)
        (2.55, _tp(other, ME, "10 15 00 03 01 00 CB 00")),
        (2.65, _dt(other, ME, "01 00 00 00 00 00 00 00")),
        (2.65, _dt(other, ME, "02 00 00 00 00 00 00 00")),
        # no data after the CTS: T2, abort 3; a BAM left unfinished: dropped after T1
        (2.75, _tp(peer, ME, "10 15 00 03 FF 00 CB 00")),
        (2.75, _tp(TECU, 0xFF, "20 0A 00 02 FF CA FE 00")),
        # a connection replaced by a new RTS, then aborted by its sender
        (4.25, _tp(other, ME, "10 15 00 03 FF 00 CB 00")),
        (4.35, _tp(other, ME, "10 0E 00 02 FF 00 CB 00")),
        (4.45, _tp(other, ME, "FF 01 FF FF FF 00 CB 00")),
        # a value command by TP (12 bytes: the first 8 count), to another address: not ours
        (4.55, _tp(TC, 0x82, "10 0C 00 02 FF 00 CB 00")),
        (4.65, _tp(TC, ME, "10 0C 00 02 FF 00 CB 00")),
        (4.75, _dt(TC, ME, "01 13 00 06 00 80 3E 00")),
        (4.85, _dt(TC, ME, "02 00 AA BB CC DD FF FF")),
        (4.95, _pd(_element(0x2, 1, 6, -1))),
        (5.45, _status()),
    ]


def _claim(address: int, name: int) -> can.Message:
    return _frame(6, 0xEE00, address, 0xFF, name.to_bytes(8, "little").hex())


def _scripted_claims() -> list[tuple[float, can.Message]]:
    """Every self-configurable address taken, then a lower NAME takes the controller's."""
    taken = [(0.45, _claim(a, 0x1000 + a)) for a in range(128, 248) if a != ME]
    return [
        *taken,
        (0.55, _claim(0x90, 0x2000)),              # a NAME moves: 0x90's old holder is gone
        (0.65, _claim(0x90, 0x1090)),              # and claims it back
        (0.75, _claim(ME, 0xFFFF_FFFF_FFFF_FFFF)),  # a higher NAME: defended
        (0.85, _claim(ME, 0x0000_0000_0000_0001)),  # a lower one: no free address, cannot claim
        (0.95, _frame(6, 0xEA00, 0x80, 0xFF, "00EE00")),   # answered from 0xFE
        (1.05, _frame(6, 0xEA00, 0x80, ME, "00EE00")),     # not its address any more
        (1.15, _status()),                                 # no address: no connection
    ]


def _scripted_transfers() -> list[tuple[float, can.Message]]:
    """A version 3 TC; a held transfer that times out (T4); retransmissions beyond the
    limit (abort 5); a transfer that ends with the end-of-message acknowledgement."""
    v3 = "10 03 FF 15 00 01 10 00"
    again = [
        (12.45, _status()), (12.55, _pd(v3)),
        (12.65, _frame(6, 0xFE0F, TC, 0xFF, "656E000000000000")),
        (12.75, _pd("11 FF FF FF FF FF FF FF")), (12.85, _pd("51 00 FF FF FF FF FF FF")),
    ]
    return [
        (0.45, _status()), (0.55, _pd(v3)),
        (0.65, _frame(6, 0xFE0F, TC, 0xFF, "656E000000000000")),
        (0.75, _pd("11 FF FF FF FF FF FF FF")), (0.85, _pd("51 00 FF FF FF FF FF FF")),
        (0.95, _cts(0, 1)),                                 # hold, then nothing: T4
        (2.45, _status()), (4.45, _status()), (6.45, _status()), (8.45, _status()),
        (10.45, _status()),                                 # the transfer response times out
        *again,
        (12.95, _cts(4, 1)), (13.05, _cts(4, 1)), (13.15, _cts(4, 1)), (13.25, _cts(4, 1)),
        (14.45, _status()),
        (14.55, _pd("71 01 00 00 00 00 FF FF")),            # transfer response: no memory
    ]


def _wheel_speed(mps: float) -> can.Message:
    raw = round(mps * 1000)
    return _frame(3, 0xFE48, TECU, 0xFF, f"{raw & 0xFF:02X}{raw >> 8:02X}0000000000FD")


def _scripted_eoma() -> list[tuple[float, can.Message]]:
    """The whole pool, 124 packets in windows of 100 and 24, acknowledged, activated; then
    metering on ground-based speed, on wheel-based speed while the ground-based one is stale,
    section states 2 and 3 (rows off), the boom stopped and started."""
    return [
        *_connect_script(), (0.85, _pd("51 00 FF FF FF FF FF FF")),
        (0.95, _cts(100, 1)), (1.05, _cts(24, 101)),
        (1.15, _tp(TC, ME, "13 5F 03 7C FF 00 CB 00")),     # end of message
        (1.25, _pd("71 00 5F 03 00 00 FF FF")), (1.35, _pd("91 00 FF FF FF FF 00 FF")),
        (1.45, _pd(_element(0x3, 1, 6, 20000))),            # 200 kg/ha
        (1.45, _pd(_element(0x8, 1, 7, 1))),                 # actual rate on change
        *[(1.55 + 0.1 * k, _speed(1.5)) for k in range(10)],
        *[(1.57 + 0.1 * k, _wheel_speed(2.0)) for k in range(30)],
        (2.45, _status()),
        (3.05, _frame(3, 0xFE49, TECU, 0xFF, "FFFFFFFFFFFFFFFF")),   # not available
        (3.15, _frame(3, 0xFE49, TECU, 0xFF, "E8030000000000")),     # 7 bytes: not a speed
        (3.25, _pd(_element(0x3, 1, 290, 0xFFFFFF79))),      # rows: on, error, not inst., on
        (3.55, _pd(_element(0x3, 1, 289, 0))),               # the boom stopped
        (3.85, _pd(_element(0x3, 1, 289, 1))),
        *[(3.95 + 0.1 * k, _speed(1.0)) for k in range(5)],
        (4.45, _status()),
    ]


def _scripted_no_memory() -> list[tuple[float, can.Message]]:
    return [*_connect_script(), (0.85, _pd("51 01 FF FF FF FF FF FF")), (2.45, _status())]


def _drop_first_cts() -> IsobusFaults:
    return IsobusFaults(dropped_cts=[DropCts(nth=3)])


def scenarios() -> list[Scenario]:
    """The recorded scenarios (see the module docstring)."""
    drive_end = DRIVE_AFTER_S + 127.7 + 1.0
    return [
        Scenario(
            "isobus-drive",
            "The example field: three passes over three rate zones, headland turns, an\n"
            "overlapping fourth pass (two rows off); the pool transfer's third CTS dropped\n"
            "(T3 abort, transfer timeout, new attempt); a TC restart of 8 s at 45 s, one of\n"
            "1 s at 80 s (NACK); TECU speed frames lost from 95 s to 97 s; row 2's module\n"
            "reads 60 % of the flow with good flags from 20 s to 35 s (the cross-row check).",
            {"law": "physical", "speed": "ground", "ddop": "valid"},
            drive_end, faults=_drop_first_cts,
            actions=((45.0, _restart(8.0)), (80.0, _restart(1.0))),
            wrong_row=(2, 0.6, 20.0, 35.0),
            drop=_speed_silent(95.0, 97.0)),
        Scenario(
            "isobus-refused",
            "A DDOP the TC refuses (ddop=broken): the client keeps quiet, nothing is metered.",
            {"law": "physical", "ddop": "broken"}, DRIVE_AFTER_S + 5.0),
        Scenario(
            "isobus-contention",
            "Non-default parameters and the wheel-based speed under 10 % slip; a lower NAME\n"
            "takes the controller's address 0x90 at 6 s (it moves to 0x81, the TC NACKs it,\n"
            "it reconnects); requests for the address claim (global, to it, to another\n"
            "address); a higher NAME contends for its new address (defended); the TC asks for\n"
            "the working-set master.",
            {"law": "paper-literal", "speed": "wheel", "address": 0x90,
             "identity_number": 4242.0, "width_m": 2.4},
            DRIVE_AFTER_S + 14.0, slip=0.1,
            faults=lambda: IsobusFaults(contend=[Contend(6.0, 0x90, 0x0000000000000001)]),
            actions=((8.0, _inject(0xEA00, 0x80, 0xFF, b"\x00\xee\x00")),
                     (8.5, _inject(0xEA00, 0x80, 0x81, b"\x00\xee\x00")),
                     (8.7, _inject(0xEA00, 0x80, 0x92, b"\x00\xee\x00")),
                     (9.0, _inject(0xEE00, 0x81, 0xFF, (0xF000000000000000).to_bytes(8,
                                                                                "little"))),
                     (9.5, _inject(0xEA00, 0xF7, 0xFF, b"\x0d\xfe\x00")))),
        Scenario(
            "isobus-scripted-tc",
            "A scripted TC: a CTS hold, a retransmission, a CTS beyond the message (abort\n"
            "250); process data commands good and bad (elements, DDIs, values, triggers),\n"
            "malformed frames, NACKs to others and to the controller (restart), a version\n"
            "request timing out, no language command, an activation refused.",
            {"law": "physical"}, 11.0, script=_scripted_tc),
        Scenario(
            "isobus-scripted-tp",
            "Long groups to the controller: a structure label with an extended label by TP,\n"
            "the TC aborting the pool transfer, BAMs (one out of order), bad RTSs, packets\n"
            "out of order, repeated, one per CTS, missing (T2), an unfinished BAM\n"
            "(T1), a connection replaced and aborted by its sender, a value command by TP.",
            {"law": "physical"}, 6.0, script=_scripted_tp),
        Scenario(
            "isobus-scripted-claims",
            "Every self-configurable address taken by others, a NAME moving, a higher NAME\n"
            "defended, a lower one taking the controller's address: cannot claim (0xFE).",
            {"law": "physical"}, 2.0, script=_scripted_claims),
        Scenario(
            "isobus-scripted-transfers",
            "A version 3 TC (the pool without the extended structure label); a held transfer\n"
            "timing out (T4, abort 3), the transfer response timing out (10 s); a second\n"
            "attempt asked for the same packets four times (abort 5); no memory after all.",
            {"law": "physical"}, 15.0, script=_scripted_transfers),
        Scenario(
            "isobus-scripted-eoma",
            "The whole pool in two CTS windows, the end-of-message acknowledgement, activation;\n"
            "metering on ground-based speed, then wheel-based while the ground-based one is\n"
            "stale (a 'not available' and a short frame ignored), sections in states 2 and 3,\n"
            "the boom stopped and started.",
            {"law": "physical"}, 5.0, script=_scripted_eoma),
        Scenario(
            "isobus-tc-no-memory",
            "A scripted TC without memory for the pool: refused before the transfer.",
            {"law": "physical"}, 3.0, script=_scripted_no_memory),
    ]


DDOP_FILE = "isobus-ddop.txt"
#: (identity number, width m, rows, latency ms, broken) of the pools the C writer is held to
DDOP_CASES = (
    (0x0F27, 3.0, 4, 430, False), (0x0F27, 3.0, 4, 430, True), (4242, 2.4, 4, 430, False),
    (1, 0.001, 1, 0, False), (0x1FFFFF, 30.0, 16, 65535, False), (77, 12.345, 7, 250, False),
    (123, 9.9995, 10, 1, True), (5, 0.75, 3, 430, False), (6, 3.0005, 13, 99, False),
)


def ddop_lines() -> list[str]:
    """``identity width_m rows latency_ms broken version hex`` per pool (version 4 and 3)."""
    lines = ["# The meter's DDOP as the Python writes it (meter_pool), for the C writer's test:",
             "# identity_number width_m rows latency_ms broken version bytes(hex)"]
    for identity, width, rows, latency, broken in DDOP_CASES:
        pool, _ = meter_pool(name=implement_name(identity).value, width_m=width, rows=rows,
                             latency_ms=latency, broken=broken)
        for version in (4, 3):
            raw = ObjectPool(pool.objects, version).to_bytes()
            lines.append(f"{identity} {width!r} {rows} {latency} {int(broken)} {version} "
                         f"{raw.hex().upper()}")
    return lines


def write_all(directory: Path = VECTOR_DIR,
              names: Iterable[str] | None = None) -> list[Path]:
    """Record the scenarios (all, or those named) into ``directory``."""
    wanted = set(names) if names is not None else None
    paths = []
    for s in scenarios():
        if wanted is not None and s.name not in wanted:
            continue
        path = directory / f"{s.name}{SUFFIX}"
        path.write_text("\n".join(record(s)) + "\n")
        paths.append(path)
    if wanted is None or DDOP_FILE in wanted:
        path = directory / DDOP_FILE
        path.write_text("\n".join(ddop_lines()) + "\n")
        paths.append(path)
    return paths


def main(argv: list[str] | None = None) -> int:
    """Write the vectors (``NAME ...`` to write only some) and print their sizes."""
    import sys
    names = (argv if argv is not None else sys.argv[1:]) or None
    for path in write_all(names=names):
        lines = path.read_text().count("\n")
        print(f"{path.name}: {lines} lines")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
