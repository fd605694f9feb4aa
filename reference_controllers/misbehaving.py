"""Reference controllers with one deliberate defect, for the must-fail DUT profiles.

A qualification suite is only as good as what it rejects: ``dut_profiles/must_fail/`` runs
these and the framework's tests check that each fails on the measurement its defect should
break. Defects (``--defect KIND:ARG``):

* ``slow-period:N`` — computes on every N-th control step only and repeats its last output in
  between (a controller whose loop runs N times slower than its period);
* ``dies-after:S`` — crashes after S seconds of control (an uncaught error: the daemon exits 1);
* ``ignores-setpoint:G`` — fertilizer: runs every setpoint as a bench target of G g/s per row.

::

    python -m reference_controllers.misbehaving --defect dies-after:10 \\
        --controller fertilizer-piecewise-pid --bus SPEC --sync --param mode=physical

In real time (``--period-ms`` = the controller's period) the defects count control steps the
same way.
"""

from __future__ import annotations

import logging
import os
import signal
import sys

import can

from hil.bus import open_bus
from hil.dut import Controller
from reference_controllers.daemon import Daemon, Stop, build_parser, parse_params
from reference_controllers.params import ParamError, ParamValue
from reference_controllers.registry import CONTROLLERS, make_controller

SYNC_ID = 0x080


class _Wrapper(Controller):
    def __init__(self, inner: Controller, period_s: float) -> None:
        self.inner = inner
        self.name = f"{inner.name}+defect"
        self.period_s = period_s
        self.steps = 0

    def configure(self, env: dict[str, str]) -> None:
        self.inner.configure(env)

    def on_start(self) -> list[can.Message]:
        return self.inner.on_start()

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.arbitration_id == SYNC_ID and not msg.is_extended_id:
            self.steps += 1
            return self.on_step(msg)
        return self.inner.on_frame(msg)

    def on_tick(self) -> list[can.Message]:
        """A control step in real time (free-running): the same step as a SYNC's."""
        self.steps += 1
        return self.on_step(None)

    def _inner_step(self, msg: can.Message | None) -> list[can.Message]:
        if msg is None:
            return self.inner.on_tick()  # type: ignore[attr-defined, no-any-return]
        return self.inner.on_frame(msg)

    def on_step(self, msg: can.Message | None) -> list[can.Message]:
        return self._inner_step(msg)


class SlowPeriod(_Wrapper):
    def __init__(self, inner: Controller, period_s: float, every: int) -> None:
        super().__init__(inner, period_s)
        if every < 2:
            raise ValueError(f"slow-period needs N >= 2, got {every}")
        self.every = every
        self.last: list[can.Message] = []

    def on_step(self, msg: can.Message | None) -> list[can.Message]:
        if (self.steps - 1) % self.every == 0:
            self.last = self._inner_step(msg)
        return list(self.last)


class DiesAfter(_Wrapper):
    def __init__(self, inner: Controller, period_s: float, after_s: float) -> None:
        super().__init__(inner, period_s)
        self.after_s = after_s

    def on_step(self, msg: can.Message | None) -> list[can.Message]:
        if self.steps * self.period_s > self.after_s:
            raise RuntimeError(f"simulated firmware crash after {self.after_s:g} s of control")
        return self._inner_step(msg)


class IgnoresSetpoint(_Wrapper):
    def __init__(self, inner: Controller, period_s: float, target_gps: float) -> None:
        super().__init__(inner, period_s)
        from plant_emulators.fertilizer.config import load_rig_config
        from plant_emulators.fertilizer.frames import FertilizerDatabase

        self.db = FertilizerDatabase.from_config(load_rig_config())
        self.setpoint_id = self.db.frame_id("FertSetpoint")
        self.target_gps = target_gps

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.arbitration_id == self.setpoint_id:
            message = self.db.db.get_message_by_frame_id(self.setpoint_id)
            signals = dict(message.decode(bytes(msg.data), decode_choices=False))
            signals.update(Mode=1, TargetFlow=self.target_gps)
            msg = can.Message(arbitration_id=msg.arbitration_id, is_extended_id=False,
                              data=message.encode(signals), timestamp=msg.timestamp)
        return super().on_frame(msg)


DEFECTS = {"slow-period": (SlowPeriod, int), "dies-after": (DiesAfter, float),
           "ignores-setpoint": (IgnoresSetpoint, float)}


def with_defect(inner: Controller, defect: str, period_s: float) -> Controller:
    kind, _, arg = defect.partition(":")
    if kind not in DEFECTS or not arg:
        raise ValueError(f"defect must be one of {', '.join(k + ':ARG' for k in DEFECTS)}, "
                         f"got {defect!r}")
    cls, convert = DEFECTS[kind]
    return cls(inner, period_s, convert(arg))   # type: ignore[arg-type]


def make(controller: str, defect: str, **params: ParamValue) -> Controller:
    """In-process factory for DUT profiles (``launch.inprocess``)."""
    try:
        inner = make_controller(controller, params, step_on_sync=True)
    except ParamError as exc:
        raise ValueError(str(exc)) from exc
    return with_defect(inner, defect, CONTROLLERS[controller].period_s)


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(stream=sys.stderr, level=logging.INFO, format="%(name)s: %(message)s")
    parser = build_parser()
    parser.prog = "python -m reference_controllers.misbehaving"
    parser.add_argument("--defect", required=True, help="KIND:ARG (see the module doc)")
    args = parser.parse_args(argv)
    if not args.bus:
        parser.error("no bus: give --bus SPEC or set AGRIHIL_BUS")
    if not args.sync and args.period_ms is None:
        parser.error("give --sync (lockstep) or --period-ms (real time)")
    if args.period_ms is not None and args.period_ms / 1e3 != CONTROLLERS[args.controller].period_s:
        parser.error(f"--period-ms must be the controller's period, "
                     f"{CONTROLLERS[args.controller].period_s * 1e3:g} ms: the defects count "
                     f"control steps")
    period_s = CONTROLLERS[args.controller].period_s
    try:
        params = parse_params(args.param)
        # a profile's [parameters] carry controller and defect for the in-process twin
        # (make()); on the command line they must agree with --controller / --defect
        for key, given in (("controller", args.controller), ("defect", args.defect)):
            value = params.pop(key, given)
            if value != given:
                raise ValueError(f"--param {key}={value} disagrees with --{key} {given}")
        controller = with_defect(make_controller(args.controller, params,
                                                 step_on_sync=args.sync),
                                 args.defect, period_s)
    except (ParamError, ValueError) as exc:
        parser.error(str(exc))
    stop = Stop()
    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    controller.configure(dict(os.environ))
    bus = open_bus(args.bus)
    logging.getLogger("misbehaving").info("%s with defect %s on %s", args.controller,
                                          args.defect, args.bus)
    try:
        Daemon(controller, bus, sync=args.sync, period_s=period_s, stop=stop).run()
    except Exception as exc:
        logging.getLogger("misbehaving").error("controller failed: %s: %s",
                                               type(exc).__name__, exc)
        return 1
    finally:
        bus.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
