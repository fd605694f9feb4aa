"""Reference controllers with one deliberate defect, for the must-fail DUT profiles.

A qualification suite is only as good as what it rejects: ``dut_profiles/must_fail/`` runs
these and the framework's tests check that each fails on the measurement its defect should
break. Defects (``--defect KIND:ARG``):

* ``slow-period:N`` — computes on every N-th control step only and repeats its last output in
  between (a controller whose loop runs N times slower than its period);
* ``dies-after:S`` — crashes after S seconds of control (an uncaught error: the daemon exits 1);
* ``ignores-setpoint:G`` — fertilizer: runs every setpoint as a bench target of G g/s per row;
* ``meters-through-stop:V`` — fertilizer: motor dead-band compensation applied to every command
  while enabled, a zero one included: any command below V volts is raised to V, so the meter
  keeps turning while the machine stands (the compensation should skip a zero target);
* ``ignores-sensor-flags`` — fertilizer: the firmware reads a flow module's Flow and never its
  status bits, so a report with BaselineReady cleared or AdcOverrange set is used as valid,
  and it has no cross-row check either (a controller whose only defence was the flags: with the
  reference's cross-row check the ~65-70 % a flagged module reads is left out after 3 s all the
  same, and the suite rightly passes it);
  sowing depth: the inclinometer's X voltage is used whatever INC_X_Status says (an open
  circuit's 0 mV reads as a 270 mm deep seed);
* ``no-plausibility`` — fertilizer: no plausibility check of the reported flow (the
  reference's ``Flow <= 3·Q + 5`` g/s): a row reading far above anything the meter can
  deliver is averaged in;
* ``no-cross-row-check`` — fertilizer: no cross-row plausibility check (the reference's
  :mod:`~reference_controllers.fertilizer.cross_row`): a row whose module freezes, steps or
  drifts with good status bits is averaged in as long as it stays below ``3·Q + 5`` g/s;
* ``speed-lowpass:T`` — fertilizer: the ground speed goes through a first-order low-pass of
  T seconds before the target flow is computed (meant to smooth the Hall node's jitter): the
  target lags every speed change by ~T;
* ``latched-setpoint`` — fertilizer: the target is read from the first FertSetpoint frame
  that enables metering and never again (a "copy on enable" that misses later changes);
  sowing depth: the same with the first DepthSetpoint that switches control on;
* ``inverted-polarity`` — sowing depth: the sign of the velocity command is inverted (the
  drive's polarity, or the cylinder's direction, taken the wrong way round at commissioning):
  every correction drives the roller the wrong way, to an end stop;
* ``needs-enable-edge`` — fertilizer: metering starts on a rising edge of the terminal's
  Enable only; after a restart mid-run Enable is already 1, so the meter stays stopped;
* ``no-fault-reset`` — sowing depth: the CiA 402 master never sets the fault-reset bit
  (controlword bit 7): a drive that tripped stays in Fault;
* ``ignores-active-rows`` — fertilizer: FertSetpoint's ActiveRows is never read; the firmware
  divides the field target by the 4 rows it was built for, whatever rows the terminal has
  switched off (rows 1..N on: each meters N/4 of its target);
* ``caps-target:G`` — fertilizer: the target flow per row is clamped to G g/s before the law
  (a rate table that ends at the meter's rated flow, a scaled integer that saturates): any
  target beyond G is metered at G, below what the meter can deliver;
* ``command-bias:F`` — fertilizer: every motor command goes out multiplied by F (an output
  scaling off by F - 1: a wrong mV per volt, a module's gain): a benign variant when the loop
  removes it (docs/guide/suites.md says why a qualification accepts F = 1.04);
* ``holds-command-at-standstill`` — sowing depth: when control is switched off (no ground
  speed) the last velocity command is kept instead of 0, so the roller keeps moving while
  the machine stands.

::

    python -m reference_controllers.misbehaving --defect dies-after:10 \\
        --controller fertilizer-piecewise-pid --bus SPEC --sync --param mode=physical

In real time (``--period-ms`` = the controller's period) the defects count control steps the
same way.
"""

from __future__ import annotations

import logging
import signal
import sys
from collections.abc import Callable
from typing import Any

import can

from hil.dut import Controller
from hil.errors import BusSpecError
from reference_controllers.daemon import Stop, build_parser, parse_params, serve
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


def _fertilizer_db() -> Any:
    from plant_emulators.fertilizer.config import load_rig_config
    from plant_emulators.fertilizer.frames import FertilizerDatabase

    return FertilizerDatabase.from_config(load_rig_config())


def _flow_controller(inner: Controller, kind: str) -> Any:
    """The reference fertilizer adapter inside ``inner`` (the defects below reach into it)."""
    from reference_controllers.fertilizer.adapter import FlowController

    if not isinstance(inner, FlowController):
        raise ValueError(f"{kind} is a fertilizer defect; {inner.name} is not a flow "
                         f"controller")
    return inner


class MetersThroughStop(_Wrapper):
    """Dead-band compensation applied to a zero command: the meter never stops while enabled."""

    def __init__(self, inner: Controller, period_s: float, min_v: float) -> None:
        super().__init__(inner, period_s)
        self.flow = _flow_controller(inner, "meters-through-stop")
        self.db = _fertilizer_db()
        self.command_id = self.db.frame_id("AnalogOutputCommand")
        self.min_mv = round(min_v * 1000.0)

    def on_step(self, msg: can.Message | None) -> list[can.Message]:
        out = self._inner_step(msg)
        if not self.flow.enabled:
            return out
        fixed = []
        for frame in out:
            if frame.arbitration_id == self.command_id:
                ch1 = float(self.db.decode(frame)[1]["Ch1Output"])
                if ch1 < self.min_mv:
                    frame = self.db.analog_output_command(ch1_mv=self.min_mv)
            fixed.append(frame)
        return fixed


class CommandBias(_Wrapper):
    """Every motor command frame goes out with its Ch1 output multiplied by ``factor``."""

    def __init__(self, inner: Controller, period_s: float, factor: float) -> None:
        super().__init__(inner, period_s)
        if not 0 < factor < 2:
            raise ValueError(f"command-bias needs a factor in (0, 2), got {factor}")
        _flow_controller(inner, "command-bias")
        self.db = _fertilizer_db()
        self.command_id = self.db.frame_id("AnalogOutputCommand")
        self.factor = factor

    def on_step(self, msg: can.Message | None) -> list[can.Message]:
        out = []
        for frame in self._inner_step(msg):
            if frame.arbitration_id == self.command_id:
                ch1 = float(self.db.decode(frame)[1]["Ch1Output"])
                frame = self.db.analog_output_command(
                    ch1_mv=min(10000, round(ch1 * self.factor)))
            out.append(frame)
        return out


class IgnoresSensorFlags(_Wrapper):
    """Every flow report is taken as BaselineReady = 1, AdcOverrange = 0 (and no cross-row
    check: see the module's list); every inclinometer frame as INC_X_Status = ok."""

    def __init__(self, inner: Controller, period_s: float, _arg: None = None) -> None:
        super().__init__(inner, period_s)
        from reference_controllers.fertilizer.adapter import FlowController

        # frame id -> (cantools message, the status signals and the values that say "good")
        self.rewrite: dict[int, tuple[Any, dict[str, int]]] = {}
        if isinstance(inner, FlowController):
            inner.rows.cross_row = None
            for can_id, row in inner.flow_rows.items():
                self.rewrite[can_id] = (inner.db.message(f"FlowModule{row}"),
                                        {"BaselineReady": 1, "AdcOverrange": 0})
        else:
            depth = _depth_controller(inner, "ignores-sensor-flags")
            incl = depth.ids["incl"]
            self.rewrite[incl] = (depth.codec.db.get_message_by_frame_id(incl),
                                  {"INC_X_Status": 0})

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        found = self.rewrite.get(msg.arbitration_id)
        if found is not None:
            message, good = found
            signals = dict(message.decode(bytes(msg.data), decode_choices=False,
                                          scaling=False))
            signals.update(good)
            msg = can.Message(arbitration_id=msg.arbitration_id,
                              is_extended_id=msg.is_extended_id,
                              data=message.encode(signals, scaling=False, strict=False),
                              timestamp=msg.timestamp)
        return super().on_frame(msg)


class IgnoresActiveRows(_Wrapper):
    """Every FertSetpoint is read with ActiveRows = 4 (the rows the firmware was built for)."""

    ROWS = 4

    def __init__(self, inner: Controller, period_s: float, _arg: None = None) -> None:
        super().__init__(inner, period_s)
        flow = _flow_controller(inner, "ignores-active-rows")
        self.setpoint_id = flow.db.frame_id("FertSetpoint")
        self.message = flow.db.message("FertSetpoint")

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.arbitration_id == self.setpoint_id and not msg.is_extended_id:
            signals = dict(self.message.decode(bytes(msg.data), decode_choices=False,
                                               scaling=False))
            signals["ActiveRows"] = self.ROWS
            msg = can.Message(arbitration_id=msg.arbitration_id, is_extended_id=False,
                              data=self.message.encode(signals, scaling=False, strict=False),
                              timestamp=msg.timestamp)
        return super().on_frame(msg)


class CapsTarget(_Wrapper):
    """The target flow per row is clamped to ``cap_gps`` before the law sees it."""

    def __init__(self, inner: Controller, period_s: float, cap_gps: float) -> None:
        super().__init__(inner, period_s)
        if cap_gps <= 0:
            raise ValueError(f"caps-target needs a cap > 0 g/s, got {cap_gps}")
        flow = _flow_controller(inner, "caps-target")
        target = flow.target_gps

        def capped() -> float:
            return min(float(target()), cap_gps)
        flow.target_gps = capped


class NoPlausibility(_Wrapper):
    """A row is valid on its flags and its age alone, whatever flow it reports."""

    def __init__(self, inner: Controller, period_s: float, _arg: None = None) -> None:
        super().__init__(inner, period_s)
        rows = _flow_controller(inner, "no-plausibility").rows

        def valid(r: Any, target_gps: float, step: int) -> bool:
            return bool(r.baseline_ready and not r.overrange
                        and step - r.arrived_step <= rows.stale_after_steps + 1e-9)
        rows.valid = valid


class NoCrossRowCheck(_Wrapper):
    """Every row that passes the single-row checks is averaged in, whatever the others read."""

    def __init__(self, inner: Controller, period_s: float, _arg: None = None) -> None:
        super().__init__(inner, period_s)
        _flow_controller(inner, "no-cross-row-check").rows.cross_row = None


class SpeedLowpass(_Wrapper):
    """The ground speeds through a first-order low-pass of ``tau_s`` before eq. 1."""

    def __init__(self, inner: Controller, period_s: float, tau_s: float) -> None:
        super().__init__(inner, period_s)
        if tau_s <= 0:
            raise ValueError(f"speed-lowpass needs a time constant > 0 s, got {tau_s}")
        self.flow = _flow_controller(inner, "speed-lowpass")
        self.alpha = period_s / (tau_s + period_s)
        self.raw = dict(self.flow.speeds)
        self.filtered = dict(self.flow.speeds)

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        self.flow.speeds.update(self.raw)
        out = super().on_frame(msg)
        self.raw = dict(self.flow.speeds)
        self.flow.speeds.update(self.filtered)
        return out

    def on_step(self, msg: can.Message | None) -> list[can.Message]:
        for source, raw in self.raw.items():
            self.filtered[source] += self.alpha * (raw - self.filtered[source])
        self.flow.speeds.update(self.filtered)
        return self._inner_step(msg)


def _depth_controller(inner: Controller, kind: str) -> Any:
    """The reference depth adapter inside ``inner``."""
    from reference_controllers.sowing_depth.adapter import DepthController

    if not isinstance(inner, DepthController):
        raise ValueError(f"{kind} is a sowing-depth defect; {inner.name} is not a depth "
                         f"controller")
    return inner


class LatchedSetpoint(_Wrapper):
    """The first setpoint frame that switches control on is the only one ever read."""

    def __init__(self, inner: Controller, period_s: float, _arg: None = None) -> None:
        super().__init__(inner, period_s)
        from reference_controllers.fertilizer.adapter import FlowController

        self.latched: can.Message | None = None
        if isinstance(inner, FlowController):
            self.setpoint_id = inner.db.frame_id("FertSetpoint")
            self.enables = lambda msg: bool(inner.db.decode(msg)[1].get("Enable", 0))
        else:
            depth = _depth_controller(inner, "latched-setpoint")
            self.setpoint_id = depth.ids["setpoint"]

            def enables(msg: can.Message) -> bool:
                sp = depth.codec.decode(msg)
                return bool(sp.enable == "on" and sp.mode == "automatic")
            self.enables = enables

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.arbitration_id == self.setpoint_id:
            if self.latched is not None:
                msg = self.latched
            elif self.enables(msg):
                self.latched = msg
        return super().on_frame(msg)


class InvertedPolarity(_Wrapper):
    """The depth loop's velocity command goes out with its sign inverted."""

    def __init__(self, inner: Controller, period_s: float, _arg: None = None) -> None:
        super().__init__(inner, period_s)
        core = _depth_controller(inner, "inverted-polarity").core
        step = core.step

        def inverted(*args: Any, **kwargs: Any) -> Any:
            speed, *gains = step(*args, **kwargs)
            return (-speed, *gains)
        core.step = inverted


class NeedsEnableEdge(_Wrapper):
    """Enable counts only after the controller has seen it 0 (an edge-triggered enable)."""

    def __init__(self, inner: Controller, period_s: float, _arg: None = None) -> None:
        super().__init__(inner, period_s)
        self.flow = _flow_controller(inner, "needs-enable-edge")
        self.setpoint_id = self.flow.db.frame_id("FertSetpoint")
        self.armed = False

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if msg.arbitration_id == self.setpoint_id and not msg.is_extended_id:
            message = self.flow.db.message("FertSetpoint")
            signals = dict(message.decode(bytes(msg.data), decode_choices=False,
                                          scaling=False))
            if not signals.get("Enable", 0):
                self.armed = True
            elif not self.armed:
                signals["Enable"] = 0
                msg = can.Message(arbitration_id=msg.arbitration_id, is_extended_id=False,
                                  data=message.encode(signals, scaling=False, strict=False),
                                  timestamp=msg.timestamp)
        return super().on_frame(msg)


class NoFaultReset(_Wrapper):
    """The controlword's fault-reset bit (7) is cleared in every RPDO2 the master sends."""

    def __init__(self, inner: Controller, period_s: float, _arg: None = None) -> None:
        super().__init__(inner, period_s)
        depth = _depth_controller(inner, "no-fault-reset")
        pdo = depth.drive.rpdo[2]
        self.cob_id = pdo.cob_id
        offsets = [v.offset for v in pdo.map if v.name == "Controlword"]
        if len(offsets) != 1 or offsets[0] % 8:
            raise ValueError("no-fault-reset: RPDO2 does not map the controlword on a byte")
        self.byte = offsets[0] // 8

    def on_step(self, msg: can.Message | None) -> list[can.Message]:
        out = []
        for frame in self._inner_step(msg):
            if frame.arbitration_id == self.cob_id and len(frame.data) > self.byte:
                data = bytearray(frame.data)
                data[self.byte] &= 0x7F
                frame = can.Message(arbitration_id=frame.arbitration_id,
                                    is_extended_id=frame.is_extended_id, data=bytes(data),
                                    timestamp=frame.timestamp)
            out.append(frame)
        return out


class HoldsCommandAtStandstill(_Wrapper):
    """Switched off (no ground speed), the depth loop repeats its last velocity, not 0."""

    def __init__(self, inner: Controller, period_s: float, _arg: None = None) -> None:
        super().__init__(inner, period_s)
        core = _depth_controller(inner, "holds-command-at-standstill").core
        step = core.step
        last = [0.0]

        def holding(target: float, depth: float, valid: bool, enabled: bool) -> Any:
            speed, *gains = step(target, depth, valid, enabled)
            if enabled:
                last[0] = speed
                return (speed, *gains)
            return (last[0], *gains)
        core.step = holding


#: kind -> (class, the argument's type; None: the kind takes no argument)
DEFECTS: dict[str, tuple[type[_Wrapper], Callable[[str], Any] | None]] = {
    "slow-period": (SlowPeriod, int), "dies-after": (DiesAfter, float),
    "ignores-setpoint": (IgnoresSetpoint, float),
    "meters-through-stop": (MetersThroughStop, float),
    "ignores-sensor-flags": (IgnoresSensorFlags, None),
    "no-plausibility": (NoPlausibility, None),
    "no-cross-row-check": (NoCrossRowCheck, None),
    "ignores-active-rows": (IgnoresActiveRows, None),
    "caps-target": (CapsTarget, float),
    "command-bias": (CommandBias, float),
    "speed-lowpass": (SpeedLowpass, float),
    "latched-setpoint": (LatchedSetpoint, None),
    "inverted-polarity": (InvertedPolarity, None),
    "needs-enable-edge": (NeedsEnableEdge, None),
    "no-fault-reset": (NoFaultReset, None),
    "holds-command-at-standstill": (HoldsCommandAtStandstill, None),
}


def _usage() -> str:
    return ", ".join(k if convert is None else k + ":ARG" for k, (_, convert) in DEFECTS.items())


def with_defect(inner: Controller, defect: str, period_s: float) -> Controller:
    """``inner`` with the defect ``KIND[:ARG]`` (see the module doc)."""
    kind, _, arg = defect.partition(":")
    if kind not in DEFECTS:
        raise ValueError(f"defect must be one of {_usage()}, got {defect!r}")
    cls, convert = DEFECTS[kind]
    if convert is None:
        if arg:
            raise ValueError(f"defect {kind} takes no argument, got {defect!r}")
        return cls(inner, period_s, None)   # type: ignore[call-arg]
    if not arg:
        raise ValueError(f"defect {kind} needs an argument ({kind}:ARG), got {defect!r}")
    return cls(inner, period_s, convert(arg))   # type: ignore[call-arg]


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
    try:
        return serve(controller, args.bus, sync=args.sync, period_s=period_s, stop=stop,
                     logger=logging.getLogger("misbehaving"), log_traceback=False,
                     started=f"{args.controller} with defect {args.defect} on {args.bus}")
    except BusSpecError as exc:
        parser.error(str(exc))

if __name__ == "__main__":
    raise SystemExit(main())
