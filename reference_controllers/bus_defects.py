"""Reference controllers with one bus defect, for the must-fail bus-conformance profiles.

Each defect is a plausible firmware bug on the bus that leaves the control law alone, so the
DUT passes the control suites and must fail its bus conformance
(``dut_profiles/must_fail/bus/*-bus-*-daemon.toml``; ``tests/hil/conformance/``). Defects
(``--defect KIND[:ARG]``):

* ``command-twice`` — every command frame goes out twice per control period (the PDO is
  queued both by the SYNC handler and by the main loop);
* ``wrong-dlc:N`` — command frames are padded (or cut) to N bytes (a driver that always sends
  8 bytes);
* ``sparse-heartbeat:N`` — only every N-th heartbeat is sent (its prescaler counts the wrong
  tick);
* ``heartbeat-stops:N`` — after N control steps no heartbeat goes out any more, while the
  control goes on (the heartbeat task died: only a consumer that judges the whole run, the
  trailing silence included, sees it);
* ``debug-frame:ID`` — every 10th control step also sends 8 bytes of internal state on
  identifier ID (hexadecimal; more than 0x7FF is a 29-bit identifier), which the databases do
  not declare (a trace left in a release build);
* ``talks-before-bootup`` — the first control step's frames go out before the boot-up message
  (initialisation in the wrong order);
* ``double-bootup`` — the boot-up message is sent again with the first control step (a second
  "boot" once the application has started).

::

    python -m reference_controllers.bus_defects --defect command-twice \\
        --controller fertilizer-piecewise-pid --bus SPEC --sync --param mode=physical
"""

from __future__ import annotations

import logging
import signal
import sys

import can

from hil.dut import Controller
from hil.errors import BusSpecError
from reference_controllers.daemon import Stop, build_parser, parse_params, serve
from reference_controllers.params import ParamError, ParamValue
from reference_controllers.registry import CONTROLLERS, make_controller

SYNC_ID = 0x080
#: the frames each reference controller sends once per control step (its commands)
COMMAND_IDS: dict[str, frozenset[int]] = {
    "fertilizer-piecewise-pid": frozenset({0x220}),
    "fertilizer-open-loop": frozenset({0x220}),
    "sowing-depth-fuzzy-pid": frozenset({0x202, 0x302}),
}
DEBUG_EVERY = 10


def _is_heartbeat(msg: can.Message) -> bool:
    return not msg.is_extended_id and 0x701 <= msg.arbitration_id <= 0x77F


def _copy(msg: can.Message, data: bytes | None = None) -> can.Message:
    payload = bytes(msg.data) if data is None else data
    return can.Message(arbitration_id=msg.arbitration_id, is_extended_id=msg.is_extended_id,
                       data=payload, dlc=len(payload))


class BusDefect(Controller):
    """The inner controller, with :meth:`step_frames` and :meth:`start_frames` changing what
    it sends; control steps (SYNC in lockstep, :meth:`on_tick` free-running) are counted."""

    def __init__(self, inner: Controller, commands: frozenset[int]) -> None:
        self.inner = inner
        self.commands = commands
        self.name = f"{inner.name}+bus-defect"
        self.steps = 0

    def configure(self, env: dict[str, str]) -> None:
        self.inner.configure(env)

    def close(self) -> None:
        close = getattr(self.inner, "close", None)
        if close is not None:
            close()

    def on_start(self) -> list[can.Message]:
        return self.start_frames(self.inner.on_start())

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        out = self.inner.on_frame(msg)
        if msg.arbitration_id == SYNC_ID and not msg.is_extended_id and out:
            self.steps += 1
            return self.step_frames(out)
        return out

    def on_tick(self) -> list[can.Message]:
        """A control step in real time (free-running), changed as a SYNC's."""
        self.steps += 1
        return self.step_frames(self.inner.on_tick())  # type: ignore[attr-defined]

    def start_frames(self, frames: list[can.Message]) -> list[can.Message]:
        return frames

    def step_frames(self, frames: list[can.Message]) -> list[can.Message]:
        return frames


class CommandTwice(BusDefect):
    def step_frames(self, frames: list[can.Message]) -> list[can.Message]:
        out = []
        for msg in frames:
            out.append(msg)
            if msg.arbitration_id in self.commands and not msg.is_extended_id:
                out.append(_copy(msg))
        return out


class WrongDlc(BusDefect):
    def __init__(self, inner: Controller, commands: frozenset[int], dlc: int) -> None:
        super().__init__(inner, commands)
        if not 0 <= dlc <= 8:
            raise ValueError(f"wrong-dlc needs 0..8 bytes, got {dlc}")
        self.dlc = dlc

    def step_frames(self, frames: list[can.Message]) -> list[can.Message]:
        return [_copy(m, bytes(m.data)[:self.dlc].ljust(self.dlc, b"\0"))
                if m.arbitration_id in self.commands and not m.is_extended_id else m
                for m in frames]


class SparseHeartbeat(BusDefect):
    def __init__(self, inner: Controller, commands: frozenset[int], every: int) -> None:
        super().__init__(inner, commands)
        if every < 2:
            raise ValueError(f"sparse-heartbeat needs N >= 2, got {every}")
        self.every = every
        self.heartbeats = 0

    def step_frames(self, frames: list[can.Message]) -> list[can.Message]:
        out = []
        for msg in frames:
            if _is_heartbeat(msg):
                self.heartbeats += 1
                if (self.heartbeats - 1) % self.every:
                    continue
            out.append(msg)
        return out


class HeartbeatStops(BusDefect):
    def __init__(self, inner: Controller, commands: frozenset[int], after_steps: int) -> None:
        super().__init__(inner, commands)
        if after_steps < 1:
            raise ValueError(f"heartbeat-stops needs N >= 1 steps, got {after_steps}")
        self.after_steps = after_steps

    def step_frames(self, frames: list[can.Message]) -> list[can.Message]:
        if self.steps <= self.after_steps:
            return frames
        return [m for m in frames if not _is_heartbeat(m)]


class DebugFrame(BusDefect):
    def __init__(self, inner: Controller, commands: frozenset[int], can_id: int) -> None:
        super().__init__(inner, commands)
        if not 0 < can_id <= 0x1FFFFFFF:
            raise ValueError(f"debug-frame needs a CAN identifier, got 0x{can_id:X}")
        self.can_id = can_id

    def step_frames(self, frames: list[can.Message]) -> list[can.Message]:
        if (self.steps - 1) % DEBUG_EVERY:
            return frames
        state = b"".join(bytes(m.data)[:2].ljust(2, b"\0") for m in frames[:4]).ljust(8, b"\0")
        return [*frames, can.Message(arbitration_id=self.can_id, data=state[:8],
                                     is_extended_id=self.can_id > 0x7FF)]


class TalksBeforeBootup(BusDefect):
    def start_frames(self, frames: list[can.Message]) -> list[can.Message]:
        first_step = self.inner.on_tick()  # type: ignore[attr-defined]
        return [*first_step, *frames]


class DoubleBootup(BusDefect):
    def __init__(self, inner: Controller, commands: frozenset[int]) -> None:
        super().__init__(inner, commands)
        self.bootup: list[can.Message] = []

    def start_frames(self, frames: list[can.Message]) -> list[can.Message]:
        self.bootup = [_copy(m) for m in frames if _is_heartbeat(m)]
        return frames

    def step_frames(self, frames: list[can.Message]) -> list[can.Message]:
        if self.steps == 1:
            return [*self.bootup, *frames]
        return frames


#: kind → (class, converter of the argument, or None: the defect takes none)
DEFECTS: dict[str, tuple[type[BusDefect], object]] = {
    "command-twice": (CommandTwice, None),
    "wrong-dlc": (WrongDlc, int),
    "sparse-heartbeat": (SparseHeartbeat, int),
    "heartbeat-stops": (HeartbeatStops, int),
    "debug-frame": (DebugFrame, lambda text: int(text, 16)),
    "talks-before-bootup": (TalksBeforeBootup, None),
    "double-bootup": (DoubleBootup, None),
}


def with_defect(inner: Controller, controller: str, defect: str) -> Controller:
    """``inner`` (the reference controller called ``controller``) with ``defect``.

    Raises
    ------
    ValueError
        Unknown defect, a missing or bad argument, or an unknown controller (all named).
    """
    kind, sep, arg = defect.partition(":")
    if kind not in DEFECTS:
        raise ValueError(f"defect must be one of {', '.join(DEFECTS)}, got {defect!r}")
    if controller not in COMMAND_IDS:
        raise ValueError(f"no command frames known for controller {controller!r}")
    cls, convert = DEFECTS[kind]
    commands = COMMAND_IDS[controller]
    if convert is None:
        if sep:
            raise ValueError(f"defect {kind} takes no argument, got {defect!r}")
        return cls(inner, commands)
    if not arg:
        raise ValueError(f"defect {kind} needs an argument ({kind}:ARG)")
    return cls(inner, commands, convert(arg))  # type: ignore[call-arg, operator]


def make(controller: str, defect: str, **params: ParamValue) -> Controller:
    """In-process factory for DUT profiles (``launch.inprocess``)."""
    try:
        inner = make_controller(controller, params, step_on_sync=True)
    except ParamError as exc:
        raise ValueError(str(exc)) from exc
    return with_defect(inner, controller, defect)


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(stream=sys.stderr, level=logging.INFO, format="%(name)s: %(message)s")
    parser = build_parser()
    parser.prog = "python -m reference_controllers.bus_defects"
    parser.add_argument("--defect", required=True, help="KIND[:ARG] (see the module doc)")
    args = parser.parse_args(argv)
    if not args.bus:
        parser.error("no bus: give --bus SPEC or set AGRIHIL_BUS")
    if not args.sync and args.period_ms is None:
        parser.error("give --sync (lockstep) or --period-ms (real time)")
    period_s = CONTROLLERS[args.controller].period_s
    if args.period_ms is not None:
        period_s = args.period_ms / 1000.0
    try:
        params = parse_params(args.param)
        # a profile's [parameters] carry controller and defect for the in-process twin
        for key, given in (("controller", args.controller), ("defect", args.defect)):
            value = params.pop(key, given)
            if value != given:
                raise ValueError(f"--param {key}={value} disagrees with --{key} {given}")
        if not args.sync:
            params.setdefault("period_s", str(period_s))
        controller = with_defect(make_controller(args.controller, params,
                                                 step_on_sync=args.sync),
                                 args.controller, args.defect)
    except (ParamError, ValueError) as exc:
        parser.error(str(exc))
    stop = Stop()
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    try:
        return serve(controller, args.bus, sync=args.sync, period_s=period_s, stop=stop,
                     logger=logging.getLogger("bus_defects"), log_traceback=False,
                     started=f"{args.controller} with bus defect {args.defect} on {args.bus}")
    except BusSpecError as exc:
        parser.error(str(exc))

if __name__ == "__main__":
    raise SystemExit(main())
