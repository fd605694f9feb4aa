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
  a defended claim, the wheel-based speed variant, non-default parameters.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import can

from hil.isobus.can_id import encode_id
from hil.isobus.faults import Contend, DropCts, IsobusFaults
from hil.isobus.field import load_field, load_prescription
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.wire import VirtualWire
from hil.rig.device import Device
from plant_emulators.fertilizer.frames import FertilizerDatabase
from reference_controllers.fertilizer.isobus_mode import IsobusFlowController
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

    def __init__(self, controller: IsobusFlowController) -> None:
        self.ctl = controller
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
            self._feed(self._db.encode(f"FlowModule{row}", {
                "Flow": self._last_target, "WindowMass": self._last_target, "Counter": 1,
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


def _tractor(slip: float, faults: IsobusFaults) -> Tractor:
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    return Tractor(TractorSetup(fld, rx, drive_after_s=DRIVE_AFTER_S, wheel_slip=slip),
                   faults=faults)


def record(s: Scenario) -> list[str]:
    """Run ``s`` and return the vector file's lines."""
    tractor = _tractor(s.slip, s.faults())
    ctl = IsobusFlowController(str(s.params["law"]),
                               {k: v for k, v in s.params.items() if k != "law"})
    node = RecordingNode(ctl)
    wire = VirtualWire([tractor.network, node], drop=s.drop)
    for at_s, action in s.actions:
        wire.run_until(at_s)
        action(tractor, wire)
    wire.run_until(s.end_s)
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
            "1 s at 80 s (NACK); TECU speed frames lost from 95 s to 97 s.",
            {"law": "physical", "speed": "ground", "ddop": "valid"},
            drive_end, faults=_drop_first_cts,
            actions=((45.0, _restart(8.0)), (80.0, _restart(1.0))),
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
    ]


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
