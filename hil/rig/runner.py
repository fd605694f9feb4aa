"""The one loop: a rig, a DUT, a bus, a clock, a scenario and a recorder.

Each tick the physics advances; scenario events apply; devices whose time has come send their
frames; traces get a row when due; then the clock completes the step: SYNC goes out when due
and, in lockstep, the step waits for the DUT's command frames (or its step-end frame, see
:mod:`hil.clock.sync`). In lockstep the loop jumps
straight from one due time to the next (several physics steps per call, the same floats as
single steps), which is what makes a 60 s run take a fraction of a second.

Whatever goes wrong (bus error, DUT silent or dead, Ctrl-C) the recorder writes what it has,
the DUT is stopped and the rig closed.
"""

from __future__ import annotations

import math
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from functools import partial
from typing import Any

import can
import numpy as np

from hil.bus import open_bus
from hil.bus.inline import InlineBus
from hil.clock import StepOrderError, SyncBarrier, is_step_end, make_clock
from hil.dut.base import DutError, DutRunner, DutSetupError, DutStopped
from hil.dut.inprocess import InProcessDut
from hil.errors import BusError, ConfigError, StepTimeoutError
from hil.record import Recorder, Verdict
from hil.record.traces import write_npz
from hil.rig import checkpoint
from hil.rig.base import Rig, RigContext
from hil.rig.busload import BusLoad
from hil.rig.device import Device
from hil.rig.run_data import RunOptions, RunResult
from hil.rig.scenario import Scenario

#: lockstep on the embedded software bus: the rig polls for the DUT's answer this long before
#: it sleeps (it waits anyway; this spares it a wake-up per step, ~35-45 µs on a VM)
LOCKSTEP_BUSY_POLL_US = 300.0


class CommandIdsError(ConfigError):
    """A profile's ``wiring.command_ids`` lists a frame the DUT does not send as a command.

    That is, not one the rig waits for after each SYNC as the DUT has configured the rig's
    nodes (a CANopen master that moved its drive's RPDOs elsewhere).
    """


def bus_load_refusal(bus: str, clock: str) -> str | None:
    """Why ``bus`` and ``clock`` cannot carry a bus load, or None if they can.

    Load needs real time and a wire with a bit rate: the paced software bus or a physical bus.

    Parameters
    ----------
    bus : str
        The bus spec of the run.
    clock : str
        The clock of the run.

    Returns
    -------
    str or None
        The reason, to follow "bus load ..." in a message; None when the load can run.
    """
    if clock != "realtime":
        return "needs the realtime clock (lockstep time has no wire to load)"
    if bus in ("inline", "virtual") or bus.startswith("virtual:"):
        return f"needs a bus with a bit rate; {bus!r} has none (use softbus)"
    if bus.startswith("socketcan:vcan"):
        return f"needs a bus with a bit rate; {bus} is a kernel vcan, which has none"
    return None


def _check_bus_load(scenario: Scenario, options: RunOptions) -> None:
    if not scenario.bus_load:
        return
    why = bus_load_refusal(options.bus, options.clock)
    if why:
        raise ConfigError(f"scenario {scenario.name}: bus_load = {scenario.bus_load} {why}",
                          key="bus_load")


@contextmanager
def _start_bus_load(spec: str, fraction: float, bitrate_bps: int,
                    rec: Recorder) -> Iterator[BusLoad]:
    """Other ECUs' traffic on the bus, from a node of its own, for the rest of the run."""
    load_bus = open_bus(spec)
    try:
        with BusLoad(load_bus, fraction, bitrate_bps) as load:
            rec.meta["bus_load"] = load.describe()
            yield load
    finally:
        load_bus.shutdown()


class _Loop:
    """State of one run; :func:`run_scenario` is the public face."""

    def __init__(self, rig: Rig, scenario: Scenario, bus: can.BusABC, rec: Recorder,
                 clock_mode: str, options: RunOptions) -> None:
        self.rig = rig
        self.scenario = scenario
        self.bus = bus
        self.rec = rec
        self.options = options
        self.clock = make_clock(clock_mode, rig.physics_period_s)
        self.dt = rig.physics_period_s
        self.frames_tx = 0
        self.frames_rx = 0
        self.barrier = SyncBarrier(bus, period_ticks=max(1, round(rig.control_period_s / self.dt)),
                                   await_ids=rig.command_ids(), dispatch=self.intake,
                                   timeout_s=options.step_timeout_s,
                                   await_any=rig.await_any_command,
                                   on_send=self._on_sync_sent)
        self.clock.add_participant(self.barrier)
        self._log_frame = rec.log_frame
        self._log_unheard = rec.log_unheard
        self._now = self.clock.now
        #: False without bus log files (a campaign's measurements-only sample): the recorder
        #: would drop every frame, so they are not handed to it (~570,000 calls, ~0.6 s of CPU
        #: per depth sample); bus conformance, which reads the log, runs only with the files
        self._logging = bool(options.record_bus)
        #: set by run_scenario: power-cycles the DUT (scenario event dut = "restart")
        self.restart_dut: Callable[[], dict[str, Any]] | None = None
        #: set by run_scenario: raises DutError when the DUT is gone. Lockstep finds a dead DUT
        #: at the next SYNC (no answer); real time calls this once per control period, so a
        #: crash ends the run there instead of after the scenario's full length
        self.check_dut: Callable[[], None] | None = None
        self._flood_limit = options.max_dut_frames_per_period
        #: arbitration ids of other nodes on the bus (a bus load generator): logged, not handled
        self.foreign_ids: frozenset[int] = frozenset()
        self._flood_window = -1
        self._flood_count = 0
        #: the DUT's command frames, and when the last one arrived (simulated time): in real
        #: time a DUT silent for longer than ``silence_limit_s`` has stopped answering (in
        #: lockstep the SYNC barrier's timeout says it)
        self.command_ids = frozenset(rig.command_ids())
        #: the profile's list of them, and whether a command frame came since the last check
        self.declared_ids = options.command_ids
        self._commanded = False
        #: None until the DUT's first command frame: only a DUT that answered can stop
        #: answering (a DUT silent by design, a CANopen master's test, say, is left alone)
        self.last_command_s: float | None = None
        self.silence_limit_s = options.step_timeout_s
        #: lockstep: the first frame that straddled two steps, raised a control period later
        self._straddle: StepOrderError | None = None
        #: per device, the tick it is due next (set by :meth:`run`); a device that takes a
        #: frame is asked again (a received frame may start a timer: a transport session, a
        #: reconfigured event timer), and the earliest such tick waits in ``_rx_due``
        self._device_due: list[int] = []
        self._rx_due = math.inf
        #: set by run_scenario: the run's prefix key (:mod:`hil.rig.checkpoint`), None when
        #: it cannot be held
        self.prefix_key: tuple[Any, ...] | None = None
        #: in a copy resumed from a checkpoint: the run it continues as
        self.resumed: checkpoint.Resume | None = None

    def _log(self, msg: can.Message, *, rx: bool) -> None:
        if self._logging:
            self._log_frame(msg, self._now(), rx=rx)

    def _on_sync_sent(self, sync: can.Message) -> None:
        """Let the rig's own nodes hear its SYNC (a bus does not echo a sender's frames).

        Their SYNC-triggered TPDOs follow the SYNC on the bus, as in CANopen.
        """
        self._log(sync, rx=False)
        t = self.clock.time_s
        for device in self.rig.devices:
            if device.accepts(sync):
                for reply in device.on_frame(sync, t):
                    self.send(reply)

    def send(self, msg: can.Message) -> None:
        try:
            self.bus.send(msg)
        except can.CanError as exc:
            raise BusError(f"cannot send frame 0x{msg.arbitration_id:X} at "
                           f"t={self.clock.time_s:.3f} s: {exc}") from exc
        self.frames_tx += 1
        if self._logging:
            self._log_frame(msg, self._now(), rx=False)

    def intake(self, msg: can.Message) -> None:
        if is_step_end(msg):    # bench control (lockstep's barrier reads it), not traffic
            self.barrier.step_ends += 1
            return
        foreign = msg.arbitration_id in self.foreign_ids and msg.is_extended_id
        # a frame a fault keeps from the rig (a cut wire: Rig.admits) was never received: it
        # is logged apart (bus-unheard.log), not in the bus logs, and reaches no node
        heard = foreign or msg.is_error_frame or self.rig.admits(msg)
        if heard:
            self.frames_rx += 1
        if self._logging:
            if heard:
                self._log_frame(msg, self._now(), rx=True)
            else:
                self._log_unheard(msg, self._now())
        if msg.arbitration_id in self.command_ids:
            self.last_command_s = self.clock.time_s
            self._commanded = True
        if foreign:
            return  # another node's traffic (bus load): logged, neither rig's nor DUT's
        if self._flood_limit is not None:
            self._count_for_flood(msg)
        if msg.is_error_frame:
            self.rig.ctx.note(self.clock.time_s, "bus-error", "error frame received")
            return
        if not heard:
            return
        t = self.clock.time_s
        for i, device in enumerate(self.rig.devices):
            if device.accepts(msg):
                for reply in device.on_frame(msg, t):
                    self.send(reply)
                self._requery(i, device, t)
                return
        self.rig.on_dut_frame(msg, t)

    def follow_command_ids(self) -> None:
        """Wait on the rig's command frames as they are now, checked once per control period.

        A CANopen master that remaps its drive's RPDOs at boot moves them
        (:meth:`Rig.command_ids` follows the configuration). Once the DUT commands (a command
        frame came in the period), its configuration is in force: the profile's
        ``wiring.command_ids``, if it lists them, must be among these frames.

        Raises
        ------
        CommandIdsError
            A listed id that is not a command frame as the DUT configured the rig's nodes.
        """
        ids = frozenset(self.rig.command_ids())
        if ids != self.command_ids:
            self.rig.ctx.note(self.clock.time_s, "command-ids",
                              "the step's command frames are now "
                              + ", ".join(f"0x{i:X}" for i in sorted(ids)))
            self.command_ids = ids
            self.barrier.await_ids = ids
        if self._commanded:
            self._commanded = False
            stray = self.declared_ids - ids
            if stray:
                raise CommandIdsError(
                    f"{_ids(stray)} is not a frame the DUT sends as a command at "
                    f"t = {self.clock.time_s:.2f} s: the rig waits after each SYNC for "
                    f"{_ids(ids)}, as the DUT has configured its nodes (fix: command_ids = "
                    f"[{_ids(ids)}] or remove the key)",
                    path=self.options.command_ids_source or None, key="wiring.command_ids")

    def _requery(self, i: int, device: Device, t: float) -> None:
        """Ask a device that took a frame when it is due now; keep the earlier tick."""
        due_s = device.next_due(t)
        if not math.isfinite(due_s) or i >= len(self._device_due):
            return
        due = math.ceil(due_s / self.dt - 1e-9)
        if due < self._device_due[i]:
            self._device_due[i] = due
            self._rx_due = min(self._rx_due, due)

    def _count_for_flood(self, msg: can.Message) -> None:
        period = self.rig.control_period_s
        window = int(self.clock.time_s / period + 1e-9)
        if window != self._flood_window:
            self._flood_window, self._flood_count = window, 0
        self._flood_count += 1
        if self._flood_limit is not None and self._flood_count > self._flood_limit:
            raise DutError(
                f"the DUT flooded the bus: more than {self._flood_limit} frames within one "
                f"control period ({period * 1000:g} ms) at t={self.clock.time_s:.3f} s, the "
                f"last 0x{msg.arbitration_id:X} (limit: timing.max_frames_per_period of its "
                f"profile)")

    def drain(self) -> None:
        while True:
            msg = self.bus.recv(0.0)
            if msg is None:
                return
            self.intake(msg)

    def drain_after_step(self) -> None:
        """Lockstep, after a step ended: read what is there, which must not be the DUT's.

        The DUT only answers what the rig sends, and has said its step is over; a frame of its
        own now straddles two steps (:meth:`hil.clock.SyncBarrier.late_frame_error`). The
        first such frame is logged and its error raised one control period later, so that a
        more specific verdict on the same frames (a flood) can come first.
        """
        pending = self._straddle
        late_frame_error, t = self.barrier.late_frame_error, self.clock.time_s
        while True:
            msg = self.bus.recv(0.0)
            if msg is None:
                break
            if not is_step_end(msg):
                self.intake(msg)    # a flood is counted (and raised) here, before the straddle
            error = late_frame_error(msg, t)
            if self._straddle is None:
                self._straddle = error
        if pending is not None:
            raise pending

    def run(self) -> None:
        rig, scenario, dt = self.rig, self.scenario, self.dt
        ticks_total = round(scenario.duration_s / dt)
        trace_ticks = max(1, round(rig.trace_period_s / dt))
        events = [(round(e.at_s / dt), e) for e in scenario.events]
        next_event = 0
        for name, value in scenario.initial.items():
            rig.set_input(name, value, 0.0)
        speed = scenario.speed_at(0.0)
        if speed is not None:
            rig.set_input("ground_speed_mps", speed, 0.0)
        devices = rig.devices
        never = ticks_total + 1

        def due_tick(due_s: float) -> int:
            # a device with nothing to send says inf (Device.next_due): due after the run
            return math.ceil(due_s / dt - 1e-9) if math.isfinite(due_s) else never

        device_due = [due_tick(d.next_due(-1.0)) for d in devices]
        self._device_due = device_due
        next_device = min(device_due, default=ticks_total + 1)
        traced = rig.trace_signals()
        for name, (_, unit) in traced.items():
            self.rec.traces.declare(name, unit)
        trace_names = list(traced)
        # a rig that overrides trace_row() gives its row without building the dict
        trace_row = rig.trace_row if type(rig).trace_row is not Rig.trace_row else None
        append_row = self.rec.traces.append
        # the loop runs 100 times per simulated second: what it calls, bound once
        send, drain, advance = self.send, self.drain, rig.advance
        drain_after_step = self.drain_after_step
        clock, barrier = self.clock, self.barrier
        complete_step, tick, batches = clock.complete_step, clock.tick, clock.batches
        sync_next_due, sync_due = barrier.next_due, barrier.due
        n_events = len(events)
        event_tick = events[0][0] if events else ticks_total   # tick of the next event

        dut_check_ticks = max(1, round(rig.control_period_s / dt))
        next_dut_check = dut_check_ticks
        hold_tick = -1 if self.prefix_key is None else \
            checkpoint.first_event_tick(scenario, dt, trace_ticks) or -1
        k = 0
        try:
            clock.start()
            while True:
                t = k * dt
                # later runs may start here; not from a rig that read its scenario (at
                # construction or since): it may have shaped its state by the events
                if k == hold_tick and rig.ready_to_hold() and not rig.ctx.scenario_read:
                    resume = checkpoint.hold(self.prefix_key or (), k)
                    if resume is not None:      # this is such a later run now
                        scenario = self._continue_as(resume)
                        events = [(round(e.at_s / dt), e) for e in scenario.events]
                        n_events, next_event = len(events), 0
                        event_tick = events[0][0] if events else ticks_total
                if event_tick <= k:
                    while next_event < n_events and events[next_event][0] <= k:
                        self._apply(events[next_event][1], t)
                        next_event += 1
                    event_tick = events[next_event][0] if next_event < n_events \
                        else ticks_total
                if next_device <= k:    # only when some device is due (in order, as ever)
                    for i, device in enumerate(devices):
                        if device_due[i] <= k:
                            for msg in device.emit(t):
                                send(msg)
                            device_due[i] = due_tick(device.next_due(t))
                    next_device = min(device_due)
                if k % trace_ticks == 0:
                    if speed is not None:
                        rig.set_input("ground_speed_mps", scenario.speed_at(t) or 0.0, t)
                    if trace_row is not None:
                        append_row(t, trace_row())
                    else:
                        signals = rig.trace_signals()
                        append_row(t, [signals[name][0] for name in trace_names])
                complete_step()
                if self._rx_due < next_device:    # a device that took a frame is due sooner
                    next_device = int(self._rx_due)
                self._rx_due = math.inf
                if k >= ticks_total:
                    if self._straddle is not None:
                        raise self._straddle
                    break
                target = min(ticks_total, sync_next_due(k), (k // trace_ticks + 1) * trace_ticks,
                             next_device, event_tick)
                if batches:
                    # lockstep: the DUT only acts on what the rig sends, and the barrier read
                    # its whole step; what is left now straddles two steps (an error)
                    if sync_due(k):
                        drain_after_step()
                        self.follow_command_ids()
                    n = max(1, target - k)
                    k = tick(n)
                    advance(n, dt)
                else:
                    # at least one tick: a device that wants to send again at once (its
                    # next_due just after now) is served at the next tick, not in a loop
                    # that never lets the clock move (lockstep's n >= 1 above)
                    target = max(target, k + 1)
                    while k < target:   # real time: one physics step per tick
                        k = tick()
                        drain()
                        advance(1, dt)
                        if self._rx_due < target:
                            target = max(k, int(self._rx_due))
                            next_device = min(next_device, target)
                            self._rx_due = math.inf
                    if self.check_dut is not None and k >= next_dut_check:
                        self.follow_command_ids()
                        self.check_dut()
                        self._check_answering()
                        next_dut_check = k + dut_check_ticks
        finally:
            self.rec.timing = self.clock.stop()

    def _continue_as(self, resume: checkpoint.Resume) -> Scenario:
        """In a copy resumed from a checkpoint: become the run ``resume`` asks for.

        Its scenario (the same up to now but for name, description and later events), its
        output directory, run id, start time and metadata; the state is the checkpoint's.
        """
        rec = self.rec
        for key in self.options.extra_meta:
            rec.meta.pop(key, None)
        self.resumed, self.scenario, self.options = resume, resume.scenario, resume.options
        self.rig.ctx.scenario = resume.scenario
        self.rig.resume_held()
        rec.out_dir = resume.options.out_dir
        rec.out_dir.mkdir(parents=True, exist_ok=True)
        rec.run_id, rec.started_at = uuid.uuid4().hex[:12], resume.started_at
        rec.meta.update({"scenario": resume.scenario.name, **resume.options.extra_meta,
                         "continued_from_checkpoint_s": self.clock.time_s})
        return resume.scenario

    def _check_answering(self) -> None:
        """Real time: fail the run of a DUT whose command frames stopped for longer than the limit.

        That is a hang, which fails the run as a crash does. A DUT that never sent one is not judged
        here (in lockstep it fails the first SYNC).
        """
        if not self.command_ids or self.last_command_s is None:
            return
        silent_s = self.clock.time_s - self.last_command_s
        if silent_s > self.silence_limit_s:
            raise DutStopped("stopped answering",
                             detail=f"no command frame for {silent_s:.1f} s (limit "
                                    f"{self.silence_limit_s:g} s)", at_s=self.last_command_s)

    def _apply(self, event: Any, t: float) -> None:
        if event.set:
            for name, value in event.set.items():
                self.rig.set_input(name, value, t)
            self.rig.ctx.note(t, "set", ", ".join(f"{k}={v}" for k, v in event.set.items()))
        elif event.fault:
            self.rig.set_fault(event.fault, True, event.target, t)
            self.rig.ctx.note(t, "fault", f"{event.fault} on {event.target}")
        elif event.clear:
            self.rig.set_fault(event.clear, False, event.target, t)
            self.rig.ctx.note(t, "fault-cleared", f"{event.clear} on {event.target}")
        elif event.dut == "restart":
            if self.restart_dut is None:
                raise ConfigError("this run cannot restart its DUT", key="events.dut")
            before = self.restart_dut()
            self.barrier.dut_restarted()    # it announces its step-end frames afresh
            self.last_command_s = self.clock.time_s    # a fresh DUT: its silence starts now
            self.rig.ctx.note(t, "dut-restart", f"the DUT was restarted (before: "
                              f"{before.get('exit', before.get('kind', '?'))})")


def _ids(ids: frozenset[int]) -> str:
    return ", ".join(f"0x{i:X}" for i in sorted(ids))


def _record_bus_stats(rec: Recorder, softbus: Any) -> None:
    """Put the software bus's counters into the record.

    A bus process that died meanwhile is noted, not raised: the run's own error, if any, is the
    one to report.
    """
    try:
        rec.meta["softbus"] = softbus.stats()
    except (BusError, OSError, ValueError) as exc:
        # OSError: SoftwareBusError of an embedded bus; ValueError: a reply cut short
        rec.meta["softbus"] = {"error": str(exc)}


#: seeds go to numpy (any non-negative integer) and into records as 64-bit integers
SEED_MAX = 2**63 - 1


def check_events(scenario: Scenario, path: str | None = None) -> None:
    """Refuse a scenario file whose events come after the end of its run.

    They would be dropped silently. Not part of :func:`check_run`: code may shorten a packaged
    scenario on purpose (a short smoke run) and keep its later events unapplied.

    Parameters
    ----------
    scenario : Scenario
        The scenario as loaded.
    path : str, optional
        The scenario file, named in the error.

    Raises
    ------
    ConfigError
        An event's time is not finite or is after ``duration_s`` (naming the event's key).
    """
    for i, event in enumerate(scenario.events):
        if not math.isfinite(event.at_s) or event.at_s > scenario.duration_s:
            raise ConfigError(f"scenario {scenario.name}: event at t = {event.at_s} s comes "
                              f"after the end of the run (duration_s = "
                              f"{scenario.duration_s:g} s) and would never happen",
                              path=path, key=f"events[{i}].at_s")


def check_run(scenario: Scenario, options: RunOptions) -> None:
    """Refuse what cannot make a meaningful run, before anything starts.

    Parameters
    ----------
    scenario : Scenario
        The scenario to run.
    options : RunOptions
        The run's options.

    Raises
    ------
    ConfigError
        Naming the key: a duration that is not a finite number of seconds above zero, a step
        timeout that is not a finite number of seconds above zero, a seed outside
        0 .. 2**63-1.
    """
    where = {"path": None}
    if not (math.isfinite(scenario.duration_s) and scenario.duration_s > 0):
        raise ConfigError(f"scenario {scenario.name}: duration_s = {scenario.duration_s} is "
                          f"not a finite number of seconds > 0", key="duration_s", **where)
    timeout = options.step_timeout_s
    if not (math.isfinite(timeout) and timeout > 0):
        raise ConfigError(f"{timeout} is not a step timeout: give a finite number of seconds "
                          f"> 0", key="step_timeout_s")
    seed = options.seed if options.seed is not None else scenario.seed
    if not 0 <= seed <= SEED_MAX:
        raise ConfigError(f"{seed} is not a seed: give an integer 0 .. 2**63-1", key="seed")


def _dut_stopped(exc: BaseException, t: float) -> tuple[str, dict[str, Any]]:
    """The run's error line for a DUT that ended it, and the facts for the record."""
    if isinstance(exc, DutStopped):
        at = exc.at_s if exc.at_s is not None else t
        line = f"the DUT {exc.what} at t = {at:.1f} s"
        detail = exc.detail.strip()
        if detail:
            line += f"; {detail[-600:]}"
        return line, {"t_s": round(at, 3), "what": exc.what}
    if isinstance(exc, StepOrderError):
        return (f"the DUT's frames straddle lockstep steps at t = {t:.1f} s ({exc})",
                {"t_s": round(t, 3), "what": "frames straddle lockstep steps"})
    if isinstance(exc, StepTimeoutError):
        return (f"the DUT stopped answering at t = {t:.1f} s ({exc})",
                {"t_s": round(t, 3), "what": "stopped answering"})
    return f"{type(exc).__name__}: {exc}", {"t_s": round(t, 3), "what": str(exc)}


def run_scenario(rig_cls: type[Rig], scenario: Scenario, dut: DutRunner,
                 options: RunOptions) -> RunResult:
    """Run ``scenario`` on a fresh ``rig_cls`` against ``dut``, writing to ``options.out_dir``.

    A DUT that dies, exits, raises or stops answering (at start-up or during the run) makes a
    failed run, not an exception: the record's ``error`` says what and when ("the DUT exited
    with SIGSEGV at t = 12.3 s") and ``dut_stopped`` holds the time. Whatever ends the run, the
    recorder writes what it has, the DUT is stopped and the rig closed.

    Parameters
    ----------
    rig_cls : type of Rig
        The rig to build for this run.
    scenario : Scenario
        What happens during the run (inputs, events, duration, seed).
    dut : DutRunner
        The controller under test; started on the run's bus and stopped at the end.
    options : RunOptions
        Where the run writes, its clock, bus, seed and limits.

    Returns
    -------
    RunResult
        The final record, the run's directory and its wall-clock and simulated durations.

    Raises
    ------
    ConfigError
        Bad options or a scenario the bus or clock cannot carry (:func:`check_run`, a bus load
        on a bus without a bit rate, the inline bus without lockstep or an in-process DUT).
    DutSetupError
        The DUT cannot be started at all.

    Notes
    -----
    A run that starts as an earlier one of this process did (lockstep, inline, the
    controller in process, measurements only) continues from that run's checkpoint at its
    first event instead of from the start, with the same result (:mod:`hil.rig.checkpoint`).
    """
    check_run(scenario, options)
    key = checkpoint.prefix_key(rig_cls, scenario, dut, options)
    holder = checkpoint.holder_for(key, scenario, rig_cls.physics_period_s)
    if holder is not None:
        resumed = checkpoint.resume(holder, scenario, options)
        if resumed is not None:
            return resumed
    try:
        result = _run_scenario(rig_cls, scenario, dut, options, key)
    except BaseException as exc:
        if checkpoint.resumed():    # a copy resumed from a checkpoint: the error goes back
            checkpoint.finish(None, exc)
        raise
    if checkpoint.resumed():        # ...and so does its result; the copy ends there
        checkpoint.finish(result)
    return result


def _run_scenario(rig_cls: type[Rig], scenario: Scenario, dut: DutRunner,
                  options: RunOptions, key: tuple[Any, ...] | None) -> RunResult:
    """:func:`run_scenario` from the start; ``key``: its prefix key, to hold it by."""
    seed = options.seed if options.seed is not None else scenario.seed
    run_id = uuid.uuid4().hex[:12]
    notes: list[dict[str, Any]] = []
    wall0 = time.perf_counter()
    sim_s = 0.0
    rec = Recorder(options.out_dir, run_id=run_id, csv=options.csv,
                   save_traces=options.save_traces,
                   **({} if options.record_bus else {"bus_log_formats": ()}))
    truth_arrays: dict[str, np.ndarray] = {}
    rec.seeds["scenario"] = seed
    rec.meta.update({"rig": rig_cls.name, "scenario": scenario.name, "clock": options.clock,
                     "duration_s": scenario.duration_s, "events": notes,
                     **options.extra_meta})
    with rec, ExitStack() as stack:
        spec = options.bus
        _check_bus_load(scenario, options)
        local_bus: Callable[[], can.BusABC] | None = None
        foreign_ids: frozenset[int] = frozenset()
        if spec == "softbus":
            # only here: its import costs ~15 ms
            from hil.softbus import SoftwareBus, SoftwareBusProcess

            # a loaded bus is paced at the rig's bit rate: load is only real on a real wire
            bitrate = rig_cls.bitrate_bps if scenario.bus_load else None
            softbus: SoftwareBus | SoftwareBusProcess
            if options.clock == "lockstep":
                embedded = stack.enter_context(SoftwareBus(port=0, bitrate=bitrate))
                # the rig joins its own bus without a socket and, while it waits for the DUT,
                # runs the bus itself (hil.softbus.server.LocalBus): two hand-offs per SYNC
                # instead of four, a step's frames in one write, no GIL ping-pong with the
                # bus thread
                local_bus = partial(embedded.local_bus, busy_poll_us=LOCKSTEP_BUSY_POLL_US)
                softbus = embedded
            else:
                # real time: the bus in a process of its own. Embedded, its thread takes the
                # rig loop's GIL whenever frames pass; on the depth rig's loaded field run
                # (2 vCPUs) that made 0.52 % of the ticks miss (invalid bench), p99 lateness
                # 294 us, longest stall 9.4 ms; in its own process 0.14 %, 57 us, 4.6 ms
                softbus = stack.enter_context(SoftwareBusProcess(port=0, bitrate=bitrate))
            spec = softbus.spec()
            stack.callback(_record_bus_stats, rec, softbus)
        elif spec == "virtual":
            spec = f"virtual:agrihil-{run_id}"
        elif spec == "inline" and (options.clock != "lockstep"
                                   or not isinstance(dut, InProcessDut)):
            raise ConfigError("the inline bus needs the lockstep clock and an in-process "
                                  "controller", key="bus")
        rec.meta["bus"] = spec
        ctx = RigContext(seed=seed, rng=np.random.default_rng(seed),
                         note=lambda t, kind, detail: notes.append(
                             {"t": round(t, 6), "kind": kind, "detail": detail}),
                         config_overrides=options.rig_config,
                         config_source=options.rig_config_source, scenario=scenario)
        if options.rig_config:
            rec.meta["rig_config_overrides"] = options.rig_config
        rig = rig_cls(ctx)
        stack.callback(rig.close)
        engines = rig.physics_engines()
        if engines:
            rec.meta["physics_engines"] = engines
        dut_env = rig.dut_environment()
        rec.meta["dut_environment"] = dut_env
        start_failure: DutStopped | None = None
        if spec == "inline":
            assert isinstance(dut, InProcessDut)
            try:
                bus: can.BusABC = dut.attach_inline(dut_env)
            except DutStopped as exc:
                start_failure = exc
                bus = InlineBus(lambda msg: [])    # nobody at the other end
        else:
            bus = local_bus() if local_bus is not None else open_bus(spec)
            announce = getattr(dut, "announce", None)
            if announce is not None:  # a DUT the rig does not start: say where to join it
                announce(options.out_dir, spec, dut_env, rig_cls.bitrate_bps)
            try:
                dut.start(spec, dut_env)
            except DutSetupError:
                bus.shutdown()
                raise
            except DutStopped as exc:   # the DUT died or stayed silent while coming up
                start_failure = exc
            if scenario.bus_load:
                load = stack.enter_context(_start_bus_load(spec, scenario.bus_load,
                                                           rig_cls.bitrate_bps, rec))
                foreign_ids = frozenset(f.arbitration_id for f in load.schedule)
        stack.callback(bus.shutdown)
        stack.callback(lambda: rec.meta.__setitem__("dut", dut.stop()))
        loop = _Loop(rig, scenario, bus, rec, options.clock, options)
        loop.foreign_ids = foreign_ids
        loop.prefix_key = key
        loop.restart_dut = lambda: dut.restart(spec, dut_env)
        loop.check_dut = dut.check
        if options.clock == "lockstep":
            loop.barrier.alive = dut.check    # a crash ends the step at once, named
            # a Python controller in a thread of this process answers SYNC with frames in any
            # order and cannot mark its steps (hil.dut.inprocess does not send the step-end
            # frame): its frames after the command are read as they come, as before (only
            # the inline bus, which calls it directly, makes its runs reproducible)
            loop.barrier.check_order = not isinstance(dut, InProcessDut)
        try:
            if start_failure is not None:
                raise start_failure
            loop.run()
            dut.check()
        except (StepTimeoutError, StepOrderError, DutError) as exc:
            # the run ended because of the DUT: the record says so and the caller gets
            # the record of a failed run, not a traceback
            rec.verdict = Verdict.ERROR
            rec.error, rec.meta["dut_stopped"] = _dut_stopped(exc, loop.clock.time_s)
            notes.append({"t": round(loop.clock.time_s, 6), "kind": "run-ended",
                          "detail": rec.error})
        finally:
            if loop.resumed is not None:    # a copy resumed as another run: it is that run
                options, wall0 = loop.options, loop.resumed.wall0
            sim_s = loop.clock.time_s
            rec.meta["truth"] = rig.truth()
            truth_arrays = rig.truth_arrays() or {}
            if truth_arrays and options.save_traces:
                write_npz(options.out_dir / "truth.npz", truth_arrays)
            rec.meta["frames"] = {"tx": loop.frames_tx, "rx": loop.frames_rx}
            if loop.barrier.step_ends:  # only a DUT that marks its steps: others' records
                rec.meta["frames"]["step_ends"] = loop.barrier.step_ends   # stay as they were
            rec.meta["wall_s"] = time.perf_counter() - wall0
            rec.meta["sim_s"] = sim_s
    wall = time.perf_counter() - wall0
    record = rec.final_record
    result = RunResult(record=record, out_dir=options.out_dir, wall_s=wall, sim_s=sim_s)
    if not options.save_traces:
        result._traces = (rec.traces.arrays(), {"time_s": "s", **rec.traces.units})
        result._truth = truth_arrays
    return result
