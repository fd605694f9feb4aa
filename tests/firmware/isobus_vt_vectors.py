"""Vectors of the reference implement's operator interface on a VT: every frame in and out.

``python tests/firmware/isobus_vt_vectors.py`` runs the Python implement with its VT client
(:class:`~reference_controllers.fertilizer.isobus_vt.IsobusVtFlowController`) against the
emulated tractor with the rig's VT on its network (TECU, TC, VT: :func:`hil.isobus.vt.server.
add_vt`), or against a scripted VT, on a :class:`~hil.isobus.wire.VirtualWire` (a SYNC every
100 ms, an ideal meter's flow frames before it, rows that can fall silent), and writes what it
was handed and what it answered, frame by frame, into ``firmware/isobus/data/vt-*.frames``
(the format of ``reference_controllers/vectors/isobus.py``; the ``#params`` line carries
``vt=yes`` and ``vt_defect``, the C build's names), and the pool's bytes for 1 to 16 rows and
the bad-pool variant into ``firmware/isobus/data/vt-pool.txt``. ctest's ``isobus_vt_vectors``
and ``isobus_vt_pool`` hold the C build (``firmware/isobus/iso_vt.c``, ``iso_pool.c``) to them;
``tests/firmware/test_isobus_vt_firmware.py`` checks that they are what the Python sends today.

Scenarios:

* ``vt-operator``: the operator's scenario of ``tests/hil/isobus/vt/test_reference_vt.py``:
  power-up (the pool uploaded by TP beside the TC's DDOP, stored), the calibration entered at
  6-7.5 s, Master on at 8 s, row 3's flow lost from 14 s (its alarm), Ack at 19 s, Master off
  at 20 s, the VT restarted at 22 s (down 5 s: the pool loaded from the VT's storage);
* ``vt-defect-*``: the same scenario with each must-fail implement (``vt_defect``);
* ``vt-cross-row``: the same scenario to 21 s with row 2's module reading 60 % of the flow
  (good flags) from 10 s to 16 s: left out by the cross-row check, its alarm;
* ``vt-odd``: the rig's VT, and frames from its address it would not send (keys pressed, held,
  aborted, keys and buttons the pool lacks, numbers for other objects, a string, an empty
  message, another VT's status, answers out of turn; not a message too short for its
  function: the Python client raises IndexError on one, the C client ignores it), then a VT
  restart whose first get memory answer is lost (the client's 3 s timeout) and whose first
  load version answer is an error (the pool uploaded after all);
* ``vt-concurrent``: the rig's VT and a scripted TC letting the DDOP go while the VT pool is
  uploaded: two TP transfers at once, one to each peer;
* ``vt-no-memory``: a VT with 500 bytes of pool memory: get memory refused, quiet for good
  (end of object pool refused: ``vt-defect-bad-pool``).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import can

from hil.isobus.can_id import encode_id
from hil.isobus.field import load_field, load_prescription
from hil.isobus.network import IsobusNetwork
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.vt.operator import Operator
from hil.isobus.vt.server import VirtualTerminalServer, VtOptions, add_vt
from hil.isobus.wire import ScriptedNode, VirtualWire
from hil.rig.device import Device
from plant_emulators.fertilizer.frames import FertilizerDatabase
from reference_controllers.fertilizer.isobus_vt import IsobusVtFlowController
from reference_controllers.fertilizer.operator_pool import IDS, meter_vt_pool
from reference_controllers.vectors import params_line

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "firmware" / "isobus" / "data"
FIELDS = ROOT / "plant_emulators" / "fertilizer" / "fields"
SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
SUFFIX = ".frames"
POOL_FILE = "vt-pool.txt"
DEFECTS = ("ignores-master", "no-alarm", "bad-pool", "no-reconnect", "meters-without-vt",
           "no-store", "slow-maintenance", "ignores-calibration")
DB = FertilizerDatabase()


def frame_text(msg: can.Message) -> str:
    """``ID#DATA`` as candump writes it (8 hex digits: extended)."""
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    return f"{ident}#{bytes(msg.data).hex().upper()}"


class RecordingNode(Device):
    """The implement on the wire (SYNC every period, an ideal meter's flow frames before it;
    the rows in ``silent`` report nothing), recording every frame in and out."""

    def __init__(self, controller: IsobusVtFlowController,
                 wrong_row: tuple[int, float, float, float] | None = None) -> None:
        self.ctl = controller
        #: (row, gain, from s, to s): that row's module reads gain x the flow meanwhile
        self.wrong_row = wrong_row
        self.period_s = controller.adapter_params.period_s
        self.silent: set[int] = set()
        self.lines: list[str] = [f"> {frame_text(f)}" for f in controller.on_start()]
        self._target = 0.0

    def _feed(self, msg: can.Message) -> list[can.Message]:
        self.lines.append(f"< {frame_text(msg)}")
        out = self.ctl.on_frame(msg)
        self.lines.extend(f"> {frame_text(f)}" for f in out)
        return out

    def next_due(self, time_s: float) -> float:
        return max(self.ctl.steps * self.period_s, math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        for row in sorted(self.ctl.rows.active - self.silent):
            flow = self._target
            if self.wrong_row is not None:
                wrong, gain, start_s, end_s = self.wrong_row
                if row == wrong and start_s <= time_s < end_s:
                    flow = round(flow * gain, 2)
            self._feed(DB.encode(f"FlowModule{row}", {
                "Flow": flow, "WindowMass": flow, "Counter": 1,
                "BaselineReady": 1, "SlidingWindow": 1, "AdcOverrange": 0,
                "InterceptApplied": 0, "WindowLength": 1000}))
        out = self._feed(SYNC)
        self._target = self.ctl.target_gps()
        return out

    def accepts(self, msg: can.Message) -> bool:
        return bool(msg.is_extended_id)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        return self._feed(msg)


@dataclass(frozen=True)
class Scenario:
    """One recorded run: its parameters, the VT (the rig's, or a script), how long."""

    name: str
    description: str
    params: dict[str, str | float]
    end_s: float
    #: "operator", "odd", "concurrent", "no-memory" (the *_scenario functions)
    kind: str = "operator"
    #: (row, gain, from s, to s): that row's module reads gain x the flow, good flags
    wrong_row: tuple[int, float, float, float] | None = None


def controller(params: dict[str, str | float]) -> IsobusVtFlowController:
    """The Python implement for a vector's parameters (``vt`` is the C build's switch)."""
    rest = {k: v for k, v in params.items() if k not in ("law", "vt")}
    return IsobusVtFlowController(str(params["law"]), rest)


Run = tuple[Tractor, VirtualTerminalServer, Device, VirtualWire]


def operator_scenario(node: Device, end_s: float = 34.0,
                      silence: Callable[[set[int]], None] | None = None) -> Run:
    """The tractor (TECU, TC over the example field) with the rig's VT, ``node`` the implement:
    calibration at 6-7.5 s, Master at 8 s, row 3 silent from 14 s (``silence``), Ack at 19 s,
    Master off at 20 s, the VT restarted at 22 s (down 5 s); run to ``end_s``."""
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    tractor = Tractor(TractorSetup(fld, rx, drive_after_s=3.0))
    vt = add_vt(tractor.network)
    wire = VirtualWire([tractor.network, node])
    operator = Operator(vt)
    operator.press("Calib.", 6.0)
    operator.enter(IDS.cal_grams_in, 95.0, 7.0)
    operator.press("Back", 7.5)
    operator.press("Master", 8.0)
    wire.run_until(14.0)
    if silence is not None:
        silence({3})
    operator.acknowledge(19.0)
    operator.press("Master", 20.0)
    wire.run_until(22.0)
    vt.restart(22.0, down_s=5.0)
    wire.run_until(end_s)
    return tractor, vt, node, wire


# --- the VT going where the rig's does not ------------------------------------------------------
VT = 0x26
ME = 0x81


def _vt(hex_data: str, source: int = VT, destination: int = ME) -> can.Message:
    """VT to ECU (PGN 0xE600), from the VT's address."""
    return can.Message(arbitration_id=encode_id(5, 0xE600, source, destination),
                       data=bytes.fromhex(hex_data.replace(" ", "")), is_extended_id=True)


def _key(function: int, activation: int, object_id: int, parent: int, code: int) -> can.Message:
    return _vt(bytes([function, activation]).hex() + object_id.to_bytes(2, "little").hex()
               + parent.to_bytes(2, "little").hex() + f"{code:02X}FF")


def _number(object_id: int, value: int) -> can.Message:
    return _vt("05" + object_id.to_bytes(2, "little").hex() + "FF"
               + value.to_bytes(4, "little").hex())


#: (run time, frame "from the VT") injected on the wire in vt-odd, once connected
ODD_FRAMES: tuple[tuple[float, can.Message], ...] = (
    (6.05, _key(0x00, 1, IDS.key_master, IDS.run_keys, 1)),      # pressed: nothing yet
    (6.15, _key(0x00, 2, IDS.key_master, IDS.run_keys, 1)),      # still held
    (6.25, _key(0x00, 3, IDS.key_master, IDS.run_keys, 1)),      # aborted: no toggle
    (6.35, _key(0x01, 0, 7777, IDS.run, 9)),                     # a button it has not
    (6.45, _key(0x00, 0, 7778, IDS.run_keys, 9)),                # a key it has not
    (6.55, _number(IDS.cal_rpm_in, 300)),                        # 30.0 rpm
    (6.65, _number(IDS.cal_grams_in, 950)),                      # 95.0 g/rev: calibrated
    (6.75, _number(IDS.cal_grams_in, 0)),                        # no usable test: unchanged
    (6.85, _number(12345, 1)),                                   # not the meter's input
    (6.95, _vt("08 C8 14 03 41 42 43 FF")),                      # a string from the VT
    (7.15, _vt("")),                                             # empty
    (7.25, _vt("FE 00 FF FF 00 00 00 FF", source=0x27, destination=0xFF)),  # another VT
    (7.35, _vt("00 00 B8 0B D0 07 01 FF", destination=0x82)),  # to another ECU
    (7.45, _vt("A8 FF FF FF FF FF FF FF")),                      # a response to what?
    (7.55, _vt("C0 FF 00 00 FF FF FF FF")),                      # get memory out of turn
    (7.65, _key(0x00, 0, IDS.key_master, IDS.run_keys, 1)),      # Master on
    (7.95, _key(0x00, 0, IDS.key_calibration, IDS.run_keys, 2)),
    (8.25, _key(0x00, 0, IDS.key_back, IDS.calibration_keys, 3)),
)
ODD_RESTART_S = 10.0


class TamperedVt(Device):
    """The tractor's network with the rig's VT, some of whose answers go astray after
    ``ODD_RESTART_S``: the first answer to get memory is lost (the client waits 3 s and starts
    over), the first answer to load version says it failed (the client uploads the pool)."""

    def __init__(self, network: Device) -> None:
        self.network = network
        self.lost_memory = False
        self.failed_load = False
        self._now = 0.0

    def _tamper(self, frames: list[can.Message]) -> list[can.Message]:
        out = []
        for f in frames:
            data = bytes(f.data)
            to_me = f.is_extended_id and (f.arbitration_id >> 8) & 0x3FFFF == 0xE600 | ME
            if to_me and self._now >= ODD_RESTART_S and data[:1] == b"\xc0" \
                    and not self.lost_memory:
                self.lost_memory = True
                continue
            if to_me and self._now >= ODD_RESTART_S and data[:1] == b"\xd1" \
                    and not self.failed_load:
                self.failed_load = True
                f = can.Message(arbitration_id=f.arbitration_id, is_extended_id=True,
                                data=data[:5] + b"\x01" + data[6:], timestamp=f.timestamp)
            out.append(f)
        return out

    def next_due(self, time_s: float) -> float:
        return self.network.next_due(time_s)

    def emit(self, time_s: float) -> list[can.Message]:
        self._now = time_s
        return self._tamper(self.network.emit(time_s))

    def accepts(self, msg: can.Message) -> bool:
        return self.network.accepts(msg)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        self._now = time_s
        return self._tamper(self.network.on_frame(msg, time_s))


def odd_scenario(node: Device, end_s: float) -> VirtualTerminalServer:
    """The tractor with the rig's VT (tampered, :class:`TamperedVt`); ``ODD_FRAMES`` injected;
    the VT restarted at ``ODD_RESTART_S`` for 5 s."""
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    tractor = Tractor(TractorSetup(fld, rx, drive_after_s=3.0))
    vt = add_vt(tractor.network)
    wire = VirtualWire([TamperedVt(tractor.network), node])
    for at_s, frame in ODD_FRAMES:
        wire.run_until(at_s)
        wire.inject(frame)
    wire.run_until(ODD_RESTART_S)
    vt.restart(ODD_RESTART_S, down_s=5.0)
    wire.run_until(end_s)
    return vt


TC = 0xF7


def _pd(hex_data: str) -> can.Message:
    """Process data from the scripted TC to the implement."""
    return can.Message(arbitration_id=encode_id(5, 0xCB00, TC, ME),
                       data=bytes.fromhex(hex_data.replace(" ", "")), is_extended_id=True)


def _tc_status() -> can.Message:
    return can.Message(arbitration_id=encode_id(3, 0xCB00, TC, 0xFF),
                       data=bytes.fromhex("FEFFFFFF000000FF"), is_extended_id=True)


def _tc_cm(hex_data: str) -> can.Message:
    return can.Message(arbitration_id=encode_id(7, 0xEC00, TC, ME),
                       data=bytes.fromhex(hex_data.replace(" ", "")), is_extended_id=True)


def _scripted_tc() -> list[tuple[float, can.Message]]:
    """A TC that lets the DDOP (864 bytes, 124 packets) go while the VT pool's upload runs
    (0.8-1.8 s): status, version, language, an unknown structure label, transfer permission at
    0.85 s, CTS windows of 16 packets, end of message, transfer response, activated."""
    windows = [(0.95 + 0.1 * k, _tc_cm(f"11 {16 if k < 7 else 12:02X} {1 + 16 * k:02X} FF FF "
                                       "00 CB 00")) for k in range(8)]
    return [(0.45, _tc_status()), (0.55, _pd("10 04 FF 15 00 01 10 00")),
            (0.55, _pd("00 FF FF FF FF FF FF FF")),
            (0.65, can.Message(arbitration_id=encode_id(6, 0xFE0F, TC, 0xFF),
                               data=bytes.fromhex("656E000000000000"), is_extended_id=True)),
            (0.75, _pd("11 FF FF FF FF FF FF FF")), (0.85, _pd("51 00 FF FF FF FF FF FF")),
            *windows, (1.75, _tc_cm("13 60 03 7C FF 00 CB 00")),
            (1.85, _pd("71 00 5F 03 00 00 FF FF")), (1.95, _pd("91 00 FF FF FF FF 00 FF")),
            (2.45, _tc_status()), (4.45, _tc_status())]


def concurrent_scenario(node: Device, end_s: float) -> VirtualTerminalServer:
    """The rig's VT alone on its network and a scripted TC (:func:`_scripted_tc`): the
    implement's two TP transfers (the VT pool, the DDOP) at the same time."""
    network = IsobusNetwork()
    vt = add_vt(network)
    VirtualWire([network, ScriptedNode(_scripted_tc(), "scripted TC"), node]).run_until(end_s)
    return vt


def no_memory_scenario(node: Device, end_s: float) -> VirtualTerminalServer:
    """The tractor with a VT of 500 bytes of pool memory."""
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    tractor = Tractor(TractorSetup(fld, rx, drive_after_s=3.0))
    vt = add_vt(tractor.network, VtOptions(memory_bytes=500))
    VirtualWire([tractor.network, node]).run_until(end_s)
    return vt


def scenarios() -> list[Scenario]:
    """The recorded scenarios (see the module docstring)."""
    out = [Scenario("vt-operator",
                    "The operator's scenario against the tractor with the rig's VT: pool uploaded\n"
                    "and stored, calibration at 6-7.5 s, Master on at 8 s, row 3 silent from 14 s\n"
                    "(alarm), Ack at 19 s, Master off at 20 s, the VT restarted at 22 s for 5 s\n"
                    "(the pool loaded from storage).",
                    {"law": "physical", "vt": "yes"}, 34.0)]
    for defect in DEFECTS:
        out.append(Scenario(f"vt-defect-{defect}",
                            f"The operator's scenario with the must-fail implement "
                            f"vt_defect={defect}.",
                            {"law": "physical", "vt": "yes", "vt_defect": defect}, 34.0))
    out.append(Scenario("vt-cross-row",
                        "The operator's scenario with row 2's module reading 60 % of the flow\n"
                        "with good flags from 10 s to 16 s: the cross-row check leaves it out,\n"
                        "its alarm.",
                        {"law": "physical", "vt": "yes"}, 21.0, wrong_row=(2, 0.6, 10.0, 16.0)))
    out += [Scenario("vt-odd",
                     "The rig's VT, and frames from its address it would not send: keys pressed,\n"
                     "held, aborted, a button and a key the pool lacks, the calibration's numbers\n"
                     "(one unusable), another object's number, a string, an empty message,\n"
                     "another VT's status, a message to another ECU, answers out of\n"
                     "turn; the VT restarted at 10 s for 5 s: its first get memory answer lost\n"
                     "(3 s, start over), its first load version answer an error (upload).",
                     {"law": "physical", "vt": "yes"}, 32.0, kind="odd"),
            Scenario("vt-concurrent",
                     "The rig's VT and a scripted TC: the VT pool (1,048 bytes) and the DDOP (864\n"
                     "bytes) go by TP at the same time, each to its peer.",
                     {"law": "physical", "vt": "yes"}, 5.0, kind="concurrent"),
            Scenario("vt-no-memory", "A VT of 500 bytes: get memory refused, quiet for good.",
                     {"law": "physical", "vt": "yes"}, 8.0, kind="no-memory")]
    return out


def record(s: Scenario) -> list[str]:
    """Run ``s`` and return the vector file's lines."""
    ctl = controller(s.params)
    node = RecordingNode(ctl, s.wrong_row)
    if s.kind == "odd":
        odd_scenario(node, s.end_s)
    elif s.kind == "concurrent":
        concurrent_scenario(node, s.end_s)
    elif s.kind == "no-memory":
        no_memory_scenario(node, s.end_s)
    else:
        operator_scenario(node, s.end_s, silence=lambda rows: node.silent.update(rows))
    head = [f"# {line}" for line in s.description.splitlines()]
    head.append(f"# {ctl.steps} control steps; written by python "
                f"tests/firmware/isobus_vt_vectors.py")
    return [*head, params_line(s.params), *node.lines]


def pool_lines() -> list[str]:
    """``rows bad hex`` per pool: 1 .. 16 rows, and the bad-pool variant of four."""
    from reference_controllers.fertilizer.operator_pool import IDS as ids
    lines = ["# The meter's VT pool as the Python writes it (meter_vt_pool), for the C writer's",
             "# test (bad: the rate's output number names font 0x7777, vt_defect=bad-pool):",
             "# rows bad bytes(hex)"]
    for rows in range(1, 17):
        lines.append(f"{rows} 0 {meter_vt_pool(rows).to_bytes().hex().upper()}")
    pool = meter_vt_pool(4)
    obj = pool.get(ids.rate_out)
    assert obj is not None
    raw = bytearray(pool.to_bytes())
    raw[obj.offset + 8:obj.offset + 10] = (0x7777).to_bytes(2, "little")
    lines.append(f"4 1 {bytes(raw).hex().upper()}")
    return lines


# --- ETP: the network layer alone sending a pool of 16 rows -------------------------------------
ETP_FILE = "vt-net-etp.frames"
#: the steps (0.1 s each) at which the function sends the 16-row pool transfer to the peer
ETP_SENDS = (0, 10, 15, 20, 40)


class SteppedNetwork(Device):
    """The Python network with the implement's NAME at 0x81, stepped as the controller steps
    it (every 0.1 s; what it answers between steps goes with the next), sending the 16-row VT
    pool transfer (2,075 bytes: ETP) to 0x26 at the steps of ``ETP_SENDS`` (from an
    application the network ticks, after its transport's timeouts, as the VT client sends);
    a SYNC line marks each step in the record."""

    def __init__(self) -> None:
        from hil.isobus.network import IsobusNetwork
        from reference_controllers.fertilizer.isobus_mode import implement_name
        self.network = IsobusNetwork()
        self.port = self.network.add(implement_name(0x0F27), ME, "implement")
        self.payload = b"\x11" + meter_vt_pool(16).to_bytes()
        self.steps = 0
        self.port.run(self)
        self.lines = ["> 710#00"]
        self._replies: list[can.Message] = []
        self._now = 0.0

    def next_due(self, time_s: float) -> float:
        return max(self.steps * 0.1, math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        self._now = self.steps * 0.1
        self.lines.append("< 080#")
        out = self._replies + self.network.emit(self._now)
        self._replies = []
        self.steps += 1
        self.lines.extend(f"> {frame_text(f)}" for f in out)
        return out

    def tick(self, now_s: float) -> None:
        """The application's tick (once per step: the network ticks it every 10 ms)."""
        if self.steps in ETP_SENDS:
            self.port.send(0xE700, self.payload, VT, 5)

    def accepts(self, msg: can.Message) -> bool:
        return bool(msg.is_extended_id)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        self.lines.append(f"< {frame_text(msg)}")
        self._replies += self.network.on_frame(msg, self._now)
        return []


def _etp_cm(hex_data: str) -> can.Message:
    return can.Message(arbitration_id=encode_id(7, 0xC800, VT, ME),
                       data=bytes.fromhex(hex_data.replace(" ", "")), is_extended_id=True)


def _etp_cts(packets: int, next_packet: int, pgn: int = 0xE700) -> can.Message:
    return _etp_cm(bytes([0x15, packets]).hex() + next_packet.to_bytes(3, "little").hex()
                   + pgn.to_bytes(3, "little").hex())


def _etp_script() -> list[tuple[float, can.Message]]:
    """A peer taking the 2,075 bytes (297 packets) by ETP, and refusing it in every way."""
    return [
        (0.05, can.Message(arbitration_id=encode_id(6, 0xEE00, VT, 0xFF), is_extended_id=True,
                           data=(0xA00A_8000_0000_0001).to_bytes(8, "little"))),
        # the first: 255 packets, a hold, 40, two again (a retransmission), the last 4, EOMA
        (0.35, _etp_cts(255, 1)), (0.45, _etp_cts(0, 256)), (0.55, _etp_cts(40, 256)),
        (0.65, _etp_cts(2, 290)), (0.75, _etp_cts(4, 294)),
        (0.85, _etp_cm("17 1B 08 00 00 00 E7 00")),
        # the second: an ETP CTS for another PGN (abort 14), a TP CTS ignored before it
        (1.05, can.Message(arbitration_id=encode_id(7, 0xEC00, VT, ME), is_extended_id=True,
                           data=bytes.fromhex("110101FFFF00E700"))),
        (1.15, _etp_cts(10, 1, pgn=0xE600)),
        # the third: a CTS beyond the message (abort 15)
        (1.65, _etp_cts(10, 290)),
        # the fourth: no CTS (T3, abort 3 at 3.25 s); the fifth: the peer aborts it
        (4.25, _etp_cm("FF 02 FF FF FF 00 E7 00")),
    ]


def etp_lines() -> list[str]:
    """The network-layer vector of ETP sending (``vt-net-etp.frames``)."""
    node = SteppedNetwork()
    VirtualWire([ScriptedNode(_etp_script(), "ETP peer"), node]).run_until(5.0)
    head = ["# ETP sending: the network layer with the implement's NAME sends the VT pool transfer",
            "# of 16 rows (2,075 bytes) to 0x26 five times: taken in windows (a hold, a",
            "# retransmission, the end-of-message acknowledgement), a CTS for another PGN (abort",
            "# 14), a CTS beyond the message (abort 15), no CTS (T3, abort 3), the peer's abort.",
            f"# {node.steps} steps; written by python tests/firmware/isobus_vt_vectors.py"]
    sends = ",".join(str(k) for k in ETP_SENDS)
    return [*head, f"#params rows=16 sends={sends}", *node.lines]


def write_all(names: list[str] | None = None) -> list[Path]:
    """Record the scenarios (all, or those named) and the pool file into ``DATA``."""
    paths = []
    for s in scenarios():
        if names and s.name not in names:
            continue
        path = DATA / f"{s.name}{SUFFIX}"
        path.write_text("\n".join(record(s)) + "\n")
        paths.append(path)
    if not names or ETP_FILE in names:
        path = DATA / ETP_FILE
        path.write_text("\n".join(etp_lines()) + "\n")
        paths.append(path)
    if not names or POOL_FILE in names:
        path = DATA / POOL_FILE
        path.write_text("\n".join(pool_lines()) + "\n")
        paths.append(path)
    return paths


if __name__ == "__main__":
    for written in write_all(sys.argv[1:]):
        print(f"{written.name}: {written.read_text().count(chr(10))} lines")
