"""A reference controller as a long-running process on a CAN bus.

::

    python -m reference_controllers.daemon --controller fertilizer-piecewise-pid \\
        --bus socketcand:127.0.0.1:29536/can0 --sync --param mode=physical --param ki1=0.5

* ``--bus SPEC``: any spec :func:`hil.bus.open_bus` takes (``socketcand:HOST:PORT/CH``,
  ``virtual:NAME``, ``socketcan:vcan0`` …); default ``$AGRIHIL_BUS``.
* ``--sync``: lockstep. One control step per SYNC (0x080), nothing between.
* ``--period-ms N``: free-running. One control step every N ms on the process's own clock,
  at absolute deadlines (a late step does not shift the next; steps more than a period late
  are skipped and counted). SYNC frames are then ignored. Without either flag the daemon
  follows ``$AGRIHIL_CLOCK`` (``lockstep`` → ``--sync``) or free-runs at the controller's
  contract period (100 ms fertilizer, 10 ms depth).
* ``--mark-steps``: lockstep only. Send the step-end frame (extended id 0x1FFFFFF0, no data,
  :data:`hil.clock.STEP_END_ID`) once after the boot-up and after each answer to SYNC, so
  the rig ends each step there instead of at the command frame (docs/guide/clocks.md).
* ``--param key=value`` (repeatable): the controller's parameters; an unknown key is an error
  that names it (exit 2), as is any other bad argument.
* ``$AGRIHIL_GNSS_PORT``: the depth controller reads the GNSS receiver's NMEA there.

It sends its CANopen boot-up frame on joining the bus, logs one start line and any error to
stderr, and exits 0 on SIGTERM or SIGINT without sending anything more (1 on a bus or
controller failure). When its bus connection closes (the software bus or the rig that ran it
died, e.g. killed with SIGKILL) it logs "bus failed: … closed the connection" and exits 1 at
once: on a socketcand bus it uses agrihil's client, which reports the server's end of stream
(python-can's ignores it and would leave an orphaned daemon polling a dead socket forever).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import signal
import sys
import time
from collections.abc import Callable
from types import FrameType

import can

from hil.bus import open_bus, parse_spec
from hil.clock.sync import STEP_END_ID, SYNC_ID
from hil.dut import Controller
from hil.errors import BusError, BusSpecError
from reference_controllers.params import ParamError, ParamValue
from reference_controllers.registry import CONTROLLERS, make_controller

log = logging.getLogger("reference_controllers.daemon")
RECV_SLICE_S = 0.05          # the longest the loop blocks before it looks at the stop flag


class Stop:
    """Set by SIGTERM/SIGINT; the loop checks it before every send."""

    def __init__(self) -> None:
        self.requested = False

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        self.requested = True


def parse_params(items: list[str]) -> dict[str, ParamValue]:
    """``["k=v", …]`` → ``{k: v}`` (values stay strings; the controller converts them)."""
    out: dict[str, ParamValue] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ParamError(f"--param wants key=value, got {item!r}")
        out[key.strip()] = value.strip()
    return out


def bus_spec_for_daemon(spec: str) -> str:
    """The spec the daemon opens: a ``socketcand`` spec without a ``client=`` option gets
    ``client=agrihil``, whose receive raises when the server closes the connection.

    Parameters
    ----------
    spec : str
        The ``--bus`` spec as given.

    Returns
    -------
    str
        ``spec`` unchanged unless it is a socketcand spec that names no client.
    """
    parsed = parse_spec(spec)
    if parsed.transport != "socketcand" or "client" in parsed.options:
        return spec
    return f"{spec.strip()},client=agrihil"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m reference_controllers.daemon",
        description="Run a reference controller on a CAN bus.")
    parser.add_argument("--controller", required=True, choices=sorted(CONTROLLERS))
    parser.add_argument("--bus", default=os.environ.get("AGRIHIL_BUS"),
                        help="bus spec (default: $AGRIHIL_BUS)")
    timing = parser.add_mutually_exclusive_group()
    timing.add_argument("--sync", action="store_true",
                        help="lockstep: one control step per SYNC frame")
    timing.add_argument("--period-ms", type=float, default=None,
                        help="free-running: one control step every N ms")
    parser.add_argument("--mark-steps", action="store_true",
                        help="lockstep: end each answer to SYNC with the step-end frame")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=VALUE")
    return parser


class Daemon:
    """The receive/step/send loop of one controller on one bus."""

    def __init__(self, controller: Controller, bus: can.BusABC, *, sync: bool,
                 period_s: float, stop: Stop, clock: Callable[[], float] = time.monotonic,
                 mark_steps: bool = False) -> None:
        self.controller = controller
        #: lockstep: the step-end frame after the boot-up and after each answer to SYNC
        self.step_end = ([can.Message(arbitration_id=STEP_END_ID, is_extended_id=True, data=b"")]
                         if mark_steps and sync else [])
        self.bus = bus
        self.sync = sync
        self.period_s = period_s
        self.stop = stop
        self.clock = clock
        self.frames_in = 0
        self.frames_out = 0
        self.send_errors = 0
        self.skipped_steps = 0

    def send(self, frames: list[can.Message]) -> None:
        for msg in frames:
            if self.stop.requested:
                return
            try:
                self.bus.send(msg)
                self.frames_out += 1
            except can.CanError as exc:
                self.send_errors += 1
                if self.send_errors in (1, 10, 100) or self.send_errors % 1000 == 0:
                    log.error("cannot send 0x%X (%d send errors so far): %s",
                              msg.arbitration_id, self.send_errors, exc)

    def receive(self, timeout: float) -> None:
        msg = self.bus.recv(max(0.0, timeout))
        if msg is not None and not self.stop.requested:
            self.frames_in += 1
            self.send(self.controller.on_frame(msg))
            if (self.step_end and msg.arbitration_id == SYNC_ID and not msg.is_extended_id
                    and not msg.is_error_frame):
                self.send(self.step_end)

    def run(self) -> None:
        self.send(self.controller.on_start())
        if self.sync:
            self.send(self.step_end)    # announces it (docs/guide/clocks.md)
            while not self.stop.requested:
                self.receive(RECV_SLICE_S)
            return
        on_tick = getattr(self.controller, "on_tick", None)
        if on_tick is None:
            raise TypeError(f"{type(self.controller).__name__} cannot free-run (no on_tick)")
        start = self.clock()
        k = 1
        while not self.stop.requested:
            deadline = start + k * self.period_s
            now = self.clock()
            if now < deadline:
                self.receive(min(deadline - now, RECV_SLICE_S))
                continue
            self.send(on_tick())
            late = math.floor((self.clock() - start) / self.period_s)
            if late > k:                 # the step overran whole periods: skip them
                self.skipped_steps += late - k
                k = late
            k += 1


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(stream=sys.stderr, level=logging.WARNING,
                        format="%(name)s: %(message)s")
    log.setLevel(logging.INFO)      # our start line; other libraries' warnings and errors only
    parser = build_parser()
    args = parser.parse_args(argv)
    if not args.bus:
        parser.error("no bus: give --bus SPEC or set AGRIHIL_BUS")
    if args.period_ms is not None and not (math.isfinite(args.period_ms)
                                           and args.period_ms > 0):
        parser.error(f"--period-ms must be > 0, got {args.period_ms}")
    kind = CONTROLLERS[args.controller]
    sync = args.sync or (args.period_ms is None
                         and os.environ.get("AGRIHIL_CLOCK") == "lockstep")
    period_s = kind.period_s if args.period_ms is None else args.period_ms / 1000.0
    try:
        params = parse_params(args.param)
        if not sync and args.period_ms is not None:
            params.setdefault("period_s", str(period_s))
        controller = make_controller(args.controller, params, step_on_sync=sync)
    except ParamError as exc:
        parser.error(str(exc))
    stop = Stop()
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    timing = "sync (one step per SYNC)" if sync else f"free-running every {period_s * 1e3:g} ms"
    shown = " ".join(f"{k}={v}" for k, v in params.items()) or "defaults"
    try:
        return serve(controller, args.bus, sync=sync, period_s=period_s, stop=stop, logger=log,
                     mark_steps=args.mark_steps,
                     started=f"{args.controller} on {args.bus}, {timing}, parameters: {shown} "
                             f"(pid {os.getpid()})")
    except BusSpecError as exc:
        parser.error(str(exc))


def serve(controller: Controller, spec: str, *, sync: bool, period_s: float, stop: Stop,
          logger: logging.Logger, started: str, log_traceback: bool = True,
          mark_steps: bool = False) -> int:
    """Configure ``controller``, open its bus and run :class:`Daemon` until stopped.

    The one run loop of every daemon (the reference daemon and the must-fail ones): the bus
    is opened through :func:`bus_spec_for_daemon`, so a daemon exits when its bus closes.

    Parameters
    ----------
    controller : Controller
        The controller to run.
    spec : str
        The ``--bus`` spec as given.
    sync, period_s, stop
        As :class:`Daemon` takes them.
    logger : logging.Logger
        Where the start line and the errors go.
    started : str
        The start line (what runs, where, how).
    log_traceback : bool
        Log a controller's exception with its traceback.
    mark_steps : bool
        In lockstep, send the step-end frame after the boot-up and after each answer to SYNC.

    Returns
    -------
    int
        The exit status: 0 when stopped, 1 when the bus could not be opened or failed, or the
        controller raised.

    Raises
    ------
    BusSpecError
        ``spec`` names no bus (the caller reports it as a usage error).
    """
    try:
        controller.configure(dict(os.environ))
        bus = open_bus(bus_spec_for_daemon(spec))
    except (BusError, OSError) as exc:
        logger.error("cannot start: %s", exc)
        return 1
    logger.info("%s", started)
    try:
        Daemon(controller, bus, sync=sync, period_s=period_s, stop=stop,
               mark_steps=mark_steps).run()
    except (can.CanError, OSError) as exc:
        logger.error("bus failed: %s", exc)
        return 1
    except Exception as exc:
        (logger.exception if log_traceback else logger.error)(
            "controller failed: %s: %s", type(exc).__name__, exc)
        return 1
    finally:
        bus.shutdown()
        close = getattr(controller, "close", None)
        if close is not None:
            close()
    return 0

if __name__ == "__main__":
    raise SystemExit(main())
