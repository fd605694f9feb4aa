"""Vectors of the depth controller's ISOBUS mode: every frame in and out, per call (issue 42).

``python -m reference_controllers.vectors.isobus_depth`` runs
:class:`~reference_controllers.sowing_depth.isobus_mode.IsobusDepthController` on a
:class:`~hil.isobus.wire.VirtualWire` against the emulated tractor (TECU + Task Controller with
the depth map) or a scripted TC, beside an ideal servo cylinder and inclinometer (:class:`Drive`:
a CiA 402 drive that follows the controlword and moves the rod at the commanded velocity; the
depth is the rod position, the inclinometer's X voltage eq. 13's inverse with a count of
dither so it never reads frozen) and a GNSS receiver (the speeds go in as the serial port's
would, at the next step). It records each frame handed to the controller and the frames it
answered with, in order, so that the C firmware (``firmware/isobus/iso_depth.c``) is fed the
same and held to the same answers byte for byte (the ``isobus_depth_vectors`` ctest).

The files (``firmware/isobus/data/depth-isobus-*.frames``) are the fertilizer's format
(:mod:`reference_controllers.vectors.isobus`) with one more line: ``G SPEED`` (m/s, a valid
fix; ``G nofix``), a GNSS report since the last step. ``depth-ddop.txt``: the depth DDOP's
bytes for the C writer's test (``isobus_depth_ddop``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import can

from hil.isobus.ddop import ObjectPool
from hil.isobus.field import load_field, load_prescription
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.wire import ScriptedNode, VirtualWire
from hil.rig.device import Device
from reference_controllers.sowing_depth.isobus_mode import (
    IsobusDepthController,
    IsobusDepthParams,
    depth_pool,
    implement_name,
)
from reference_controllers.vectors import params_line
from reference_controllers.vectors.isobus import _element, _frame, _status, frame_text

__all__ = ["DATA_DIR", "DDOP_FILE", "ddop_lines", "record", "scenarios", "write_all"]

ROOT = Path(__file__).resolve().parents[2]
DATA_DIR = ROOT / "firmware" / "isobus" / "data"
FIELDS = ROOT / "plant_emulators" / "fertilizer" / "fields"
DEPTH_MAP = ROOT / "plant_emulators" / "sowing_depth" / "fields" / "depths-3zones.geojson"
SUFFIX = ".frames"
SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
INCLINOMETER_ID = 0x0CFF11A1
DRIVE_NODE = 2
TC = 0xF7
#: the inclinometer's X voltage for a depth: eq. 13 inverted (depth = -0.065 x + 270.35)
MV_PER_MM = -1.0 / 0.065


class FakeGnss:
    """The GNSS serial port as the controller polls it: the reports queued since the last step."""

    def __init__(self) -> None:
        self.pending: list[float | None] = []

    def poll(self) -> list[float | None]:
        out, self.pending = self.pending, []
        return out

    def close(self) -> None:
        """Nothing to close."""


@dataclass
class Drive:
    """An ideal CiA 402 servo cylinder (node 2) and the inclinometer that reads its depth."""

    position_mm: float = 30.0
    statusword: int = 0x0040            # switch on disabled
    operational: bool = False
    mode_set: bool = False
    velocity_mm_s: float = 0.0
    #: (from s, to s) during which the inclinometer's X status says error
    sensor_error: tuple[float, float] | None = None
    count: int = 0
    frames_out: list[can.Message] = field(default_factory=list)

    def command(self, frame: can.Message) -> None:
        """What the controller sends the drive: NMT start, the mode (RPDO3), RPDO2."""
        data = bytes(frame.data)
        if frame.arbitration_id == 0x000 and data[:2] == bytes([0x01, DRIVE_NODE]):
            self.operational = True
        elif frame.arbitration_id == 0x400 + DRIVE_NODE:
            self.mode_set = data[0] == 3
        elif frame.arbitration_id == 0x300 + DRIVE_NODE:
            controlword = int.from_bytes(data[:2], "little")
            self.velocity_mm_s = int.from_bytes(data[2:6], "little", signed=True) / 100.0
            self._transition(controlword)

    def _transition(self, controlword: int) -> None:
        state = self.statusword & 0x6F
        if controlword & 0x80:
            self.statusword = 0x0040
        elif controlword & 0x0F == 0x06 and state in (0x40, 0x21, 0x23, 0x27):
            self.statusword = 0x0021
        elif controlword & 0x0F == 0x07 and state in (0x21, 0x23, 0x27):
            self.statusword = 0x0023
        elif controlword & 0x0F == 0x0F and state in (0x23, 0x27):
            self.statusword = 0x0027

    def frames(self, time_s: float, period_s: float) -> list[can.Message]:
        """The drive's heartbeat (every 10th step), TPDO1 and the inclinometer, one step."""
        if self.statusword & 0x6F == 0x27 and self.mode_set:
            self.position_mm = min(max(self.position_mm + self.velocity_mm_s * period_s, 0.0),
                                   100.0)
        out = []
        if self.count % 10 == 0:
            state = 0x05 if self.operational else 0x00 if self.count == 0 else 0x7F
            out.append(can.Message(arbitration_id=0x700 + DRIVE_NODE, data=bytes([state]),
                                   is_extended_id=False))
        position = round(self.position_mm * 100.0)
        out.append(can.Message(arbitration_id=0x180 + DRIVE_NODE,
                               data=self.statusword.to_bytes(2, "little")
                               + position.to_bytes(4, "little", signed=True),
                               is_extended_id=False))
        error = self.sensor_error is not None and \
            self.sensor_error[0] <= time_s < self.sensor_error[1]
        x_mv = round((self.position_mm - 270.35) * MV_PER_MM) + (self.count % 3) - 1
        data = (x_mv.to_bytes(2, "little") + (2500).to_bytes(2, "little")
                + bytes([1 if error else 0, self.count & 0x0F, 0xFF, 0xFF]))
        out.append(can.Message(arbitration_id=INCLINOMETER_ID, data=data, is_extended_id=True))
        self.count += 1
        return out


class RecordingNode(Device):
    """The controller on the wire (a SYNC every period, the drive, the GNSS receiver),
    recording its frames."""

    def __init__(self, controller: IsobusDepthController, drive: Drive,
                 gnss: Callable[[float], float | str | None]) -> None:
        self.ctl = controller
        self.drive = drive
        self.gnss_at = gnss
        self.port = FakeGnss()
        controller.gnss = self.port            # type: ignore[assignment]
        self.period_s = controller.core_params.period_s
        self.lines: list[str] = [f"> {frame_text(f)}" for f in controller.on_start()]

    def _feed(self, msg: can.Message) -> list[can.Message]:
        self.lines.append(f"< {frame_text(msg)}")
        out = self.ctl.on_frame(msg)
        self.lines.extend(f"> {frame_text(f)}" for f in out)
        for frame in out:
            if not frame.is_extended_id:
                self.drive.command(frame)
        return out

    def next_due(self, time_s: float) -> float:
        return max(self.ctl.steps * self.period_s, math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        sent = []
        for frame in self.drive.frames(time_s, self.period_s):
            sent += self._feed(frame)
        speed = self.gnss_at(time_s)
        if speed != "silent":
            value = None if speed is None else float(speed)
            self.port.pending.append(value)
            self.lines.append("G nofix" if value is None else f"G {value!r}")
        sent += self._feed(SYNC)
        return [f for f in sent if f.is_extended_id]

    def accepts(self, msg: can.Message) -> bool:
        return bool(msg.is_extended_id)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        return [f for f in self._feed(msg) if f.is_extended_id]


@dataclass(frozen=True)
class Scenario:
    """One recorded run: its parameters, its peer (the tractor or a script), for how long."""

    name: str
    description: str
    params: dict[str, str | float]
    end_s: float
    #: instead of the emulated tractor, a scripted TC: (run time, frame) to send
    script: Callable[[int, int], list[tuple[float, can.Message]]] | None = None
    #: (run time, action on the tractor) in time order
    actions: tuple[tuple[float, Callable[[Tractor, VirtualWire], None]], ...] = ()
    sensor_error: tuple[float, float] | None = None
    #: the GNSS speed at a run time: m/s, None (no fix) or "silent" (no report)
    gnss: Callable[[Tractor | None, float], float | str | None] | None = None


def _tractor_speed(tractor: Tractor | None, time_s: float) -> float | str | None:
    if tractor is None:
        return 1.5 if time_s >= 1.0 else "silent"
    return round(tractor.pose(time_s).speed_m_s, 4)


def record(s: Scenario) -> list[str]:
    """Run ``s`` and return the vector file's lines."""
    ctl = IsobusDepthController(dict(s.params))
    drive = Drive(sensor_error=s.sensor_error)
    gnss = s.gnss or _tractor_speed
    tractor = None
    if s.script is None:
        fld = load_field(FIELDS / "field-rect.geojson")
        rx = load_prescription(DEPTH_MAP, frame=fld.frame)
        tractor = Tractor(TractorSetup(fld, rx, drive_after_s=3.0))
    node = RecordingNode(ctl, drive, lambda t: gnss(tractor, t))
    if s.script is not None:
        script = s.script(len(ctl.pool.to_bytes()), int(ctl.isobus.address))
        wire = VirtualWire([ScriptedNode(script, "scripted TC"), node])
    else:
        assert tractor is not None
        wire = VirtualWire([tractor.network, node])
    for at_s, action in s.actions:
        wire.run_until(at_s)
        assert tractor is not None
        action(tractor, wire)
    wire.run_until(s.end_s)
    head = [f"# {line}" for line in s.description.splitlines()]
    head.append(f"# {ctl.steps} control steps; written by python -m "
                f"reference_controllers.vectors.isobus_depth")
    return [*head, params_line(s.params), *node.lines]


def _pd(hex_data: str, me: int) -> can.Message:
    """Process data from the scripted TC to the controller at ``me``."""
    return _frame(5, 0xCB00, TC, me, hex_data)


def _tp(hex_data: str, me: int) -> can.Message:
    return _frame(7, 0xEC00, TC, me, hex_data)


def _depth(command: int, ddi: int, value: int, me: int, element: int = 1) -> can.Message:
    return _pd(_element(command, element, ddi, value), me)


def _connect(at_s: float, pool_bytes: int, me: int) -> list[tuple[float, can.Message]]:
    """Status, version, language, an unknown structure label, the transfer (CTS windows of 16
    packets, the end-of-message acknowledgement), activation: from ``at_s`` on."""
    size = pool_bytes + 1
    packets = -(-size // 7)
    script = [(at_s, _status()), (at_s + 0.1, _pd("10 04 FF 15 00 01 10 00", me)),
              (at_s + 0.1, _pd("00 FF FF FF FF FF FF FF", me)),
              (at_s + 0.2, _frame(6, 0xFE0F, TC, 0xFF, "656E000000000000")),
              (at_s + 0.3, _pd("11 FF FF FF FF FF FF FF", me)),
              (at_s + 0.4, _pd("51 00 FF FF FF FF FF FF", me))]
    t = at_s + 0.5
    for first in range(1, packets + 1, 16):
        window = min(16, packets - first + 1)
        script.append((t, _tp(f"11 {window:02X} {first:02X} FF FF 00 CB 00", me)))
        t += 0.1
    script.append((t, _tp(f"13 {size & 0xFF:02X} {size >> 8:02X} {packets:02X} FF 00 CB 00",
                          me)))
    script.append((t + 0.1, _pd(f"71 00 {pool_bytes & 0xFF:02X} {pool_bytes >> 8:02X} 00 00 FF FF",
                                me)))
    script.append((t + 0.2, _pd("91 00 FF FF FF FF 00 FF", me)))
    return script


def _statuses(start_s: float, end_s: float) -> list[tuple[float, can.Message]]:
    out = []
    t = start_s
    while t < end_s:
        out.append((t, _status()))
        t += 2.0
    return out


def _scripted_tc(pool_bytes: int, me: int) -> list[tuple[float, can.Message]]:
    """The TC sets depths good and bad, asks for values and triggers, restarts (a NACK: the
    client starts over and reconnects from its labels, no transfer), then falls silent (the
    client loses it after 6 s: the default depth)."""
    return sorted([
        *_connect(0.45, pool_bytes, me),
        *_statuses(2.45, 9.0),
        (2.75, _depth(0x3, 56, 40, me)),                  # 40 mm, no acknowledge
        (2.75, _depth(0x8, 57, 1, me)),                   # actual depth on change
        (2.75, _depth(0x4, 57, 500, me)),                 # and every 500 ms
        (2.85, _depth(0x2, 0xDFFF, -1, me, element=0)),   # the default set
        (2.85, _depth(0x2, 56, -1, me)), (2.85, _depth(0x2, 57, -1, me)),
        (2.85, _depth(0x2, 58, -1, me)),                  # a property, not process data
        (3.05, _depth(0xA, 56, 70, me)),                  # beyond the maximum: 0x80
        (3.05, _depth(0x3, 56, 5, me)),                   # below the minimum
        (3.05, _depth(0x3, 57, 40, me)),                  # not settable
        (3.05, _depth(0x3, 56, 40, me, element=0)),       # the device element: no DDI 56
        (3.05, _depth(0x3, 56, 40, me, element=9)),       # no such element
        (3.05, _depth(0x6, 57, 1, me)),                   # threshold: not offered
        (4.05, _depth(0xA, 56, 45, me)),                  # 45 mm, acknowledged
        (5.05, _frame(6, 0xE800, TC, me, f"01FFFFFF{me:02X}00CB00")),   # NACK to it: a restart
        (5.45, _status()), (5.55, _pd("10 04 FF 15 00 01 10 00", me)),
        (5.65, _frame(6, 0xFE0F, TC, 0xFF, "656E000000000000")),
        (5.75, _pd("11 41 47 44 2D 49 53 4F", me)),       # AGD-ISO: the pool it has
        (5.85, _pd("31 65 6E 00 00 00 00 FF", me)),       # en: no transfer
        (5.95, _pd("91 00 FF FF FF FF 00 FF", me)),       # activated again
        (6.05, _depth(0x2, 56, -1, me)),                  # the default until it sends one
        (7.05, _depth(0x3, 56, 35, me)),
        # no status after 8.45 s: lost at 14.45 s, the default depth (or, fallback=hold, 35)
    ], key=lambda p: p[0])


def _restart(down_s: float) -> Callable[[Tractor, VirtualWire], None]:
    def act(tractor: Tractor, wire: VirtualWire) -> None:
        tractor.tc.restart(wire.now, down_s=down_s)
    return act


def _speed_gap(start_s: float, end_s: float, nofix: bool,
               ) -> Callable[[Tractor | None, float], float | str | None]:
    def gnss(tractor: Tractor | None, time_s: float) -> float | str | None:
        if start_s <= time_s < end_s:
            return None if nofix else "silent"
        return _tractor_speed(tractor, time_s)
    return gnss


def scenarios() -> list[Scenario]:
    """The recorded scenarios."""
    return [
        Scenario(
            "depth-isobus-drive",
            "The emulated tractor on the example field with the 3-zone depth map (30 / 40 / 35\n"
            "mm), 45 s: connection, the pool transfer, the first pass into the 40 mm zone; a\n"
            "TC restart of 8 s at 30 s (lost after 6 s: the default depth, then the map again);\n"
            "the inclinometer in error from 20 s to 20.5 s (the roller held); GNSS no fix\n"
            "from 25 s to 26.5 s (speed lost).",
            {"kp0": 3.0, "ki0": 0.1, "kd0": 0.0}, 45.0,
            actions=((30.0, _restart(8.0)),), sensor_error=(20.0, 20.5),
            gnss=_speed_gap(25.0, 26.5, nofix=True)),
        Scenario(
            "depth-isobus-scripted-tc",
            "A scripted TC: the pool transferred and activated, depths good and out of range,\n"
            "requests and triggers, a restart (reconnection from the labels), then silence\n"
            "(the default depth after 6 s).",
            {"kp0": 3.0, "ki0": 0.1, "kd0": 0.0}, 16.0, script=_scripted_tc),
        Scenario(
            "depth-isobus-must-fail",
            "The scripted TC with the must-fail defects: the set-point reported as the actual\n"
            "depth, the last set-point held when the TC is lost; no GNSS for 2 s at 8 s.",
            {"kp0": 3.0, "ki0": 0.1, "kd0": 0.0, "actual": "setpoint", "fallback": "hold"},
            16.0, script=_scripted_tc, gnss=_speed_gap(8.0, 10.0, nofix=False)),
        Scenario(
            "depth-isobus-fixed",
            "The scripted TC with non-default parameters: another address and NAME, a 20-50 mm\n"
            "range with a 25 mm default, 800 ms latency, and a fixed 35 mm depth (ignores the\n"
            "map).",
            {"address": 0x84, "identity_number": 4242.0, "default_depth_mm": 25.0,
             "min_depth_mm": 20.0, "max_depth_mm": 50.0, "latency_ms": 800.0,
             "fixed_depth_mm": 35.0},
            16.0, script=_scripted_tc),
    ]


DDOP_FILE = "depth-ddop.txt"
#: (identity, width m, offset x mm, latency ms, default, min, max mm) of the pools the C
#: writer is held to
DDOP_CASES = (
    (0x0D42, 2.4, -1900, 1000.0, 30.0, 10.0, 60.0), (4242, 2.4, -1900, 800.0, 25.0, 20.0, 50.0),
    (1, 0.001, 0, 0.0, 0.5, 0.5, 0.5), (0x1FFFFF, 30.0, -30000, 10000.0, 40.5, 1.5, 100.0),
    (77, 12.345, 250, 2.5, 31.5, 12.5, 99.5), (5, 3.0005, -1, 1234.5, 35.0, 35.0, 35.0),
)


def ddop_lines() -> list[str]:
    """``identity width_m offset_x_mm latency_ms default min max version hex`` per pool."""
    lines = ["# The depth DDOP as the Python writes it (depth_pool), for the C writer's test:",
             "# identity width_m offset_x_mm latency_ms default_mm min_mm max_mm version hex"]
    for identity, width, offset, latency, default, low, high in DDOP_CASES:
        params = IsobusDepthParams(identity_number=identity, latency_ms=latency,
                                   default_depth_mm=default, min_depth_mm=low,
                                   max_depth_mm=high)
        pool, _ = depth_pool(name=implement_name(identity).value, width_m=width,
                             offset_x_mm=offset, params=params)
        for version in (4, 3):
            raw = ObjectPool(pool.objects, version).to_bytes()
            lines.append(f"{identity} {width!r} {offset} {latency!r} {default!r} {low!r} "
                         f"{high!r} {version} {raw.hex().upper()}")
    return lines


def write_all(directory: Path = DATA_DIR, names: Iterable[str] | None = None) -> list[Path]:
    """Record the scenarios (all, or those named) and the DDOP file into ``directory``."""
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
        print(f"{path.name}: {path.read_text().count(chr(10))} lines")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
