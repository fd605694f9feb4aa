"""Prefix checkpoints: runs that start alike continue from one forked copy of the first.

The depth rig's fault scenarios share seed, speed, target and DUT and differ only from their
first event on (20 s of 40); their twin (no events) is the same run without it. In lockstep
on the inline bus with the controller in process, such a run is a pure function of its
prefix: at the tick of the first event the rig, the controller and the loop are in the same
state whichever scenario follows. So the first such run forks a *holder* there: a copy of the
process that waits, frozen at that tick. A later run with the same prefix asks the holder,
which forks again; that copy swaps in the later run's scenario (its name, events, output
directory and metadata), runs from the tick to the end and sends its result back. The first
run itself goes on undisturbed.

It is a pure cache: a run that cannot be shown to have the same prefix, or that is not one
of these (another bus or clock, a DUT in another process, a bus log or trace files to
write, a process with other threads, no ``fork``), runs from the start as ever; the result
is the one the run would have had from the start (``tests/hil/rig/test_checkpoint.py``
compares every trace and measurement bit for bit).

What "the same prefix" is: the same rig class; the same options except the output
directory and the record's metadata; the same DUT (its profile's name and hash in
``extra_meta["dut_identity"]``, which a run must give to be held at all, its runner's name
and its controller's class); the same scenario apart from its name, description and events,
none of which may come before the checkpoint's tick (a trace tick, which every run of the rig
stops at, so that the state there is the same whatever the next event).
"""

from __future__ import annotations

import atexit
import contextlib
import dataclasses
import datetime as dt
import os
import pickle
import signal
import socket
import struct
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from hil.dut.inprocess import InProcessDut
from hil.rig.run_data import RunOptions, RunResult

if TYPE_CHECKING:
    from hil.dut.base import DutRunner
    from hil.rig.base import Rig
    from hil.rig.scenario import Scenario

#: holders kept alive at once (each is a forked copy of the process, mostly shared pages):
#: the oldest is let go when another is made
MAX_HOLDERS = 4
_LEN = struct.Struct("!Q")


@dataclass(frozen=True)
class Resume:
    """What a run continued from a checkpoint takes over from the run that made it."""

    scenario: Scenario
    options: RunOptions
    #: when the resumed run was asked for (``time.perf_counter``, the same clock in every
    #: process of the machine): its wall time counts from here
    wall0: float
    started_at: str


@dataclass
class _Holder:
    pid: int
    sock: socket.socket
    tick: int


#: this process's holders by prefix key (oldest first)
_holders: OrderedDict[tuple[Any, ...], _Holder] = OrderedDict()
#: in a copy resumed from a checkpoint: the socket its result goes back on
_resumed: socket.socket | None = None


def prefix_key(rig_cls: type[Rig], scenario: Scenario, dut: DutRunner,
               options: RunOptions) -> tuple[Any, ...] | None:
    """What a run's state up to its first event depends on, or None if it cannot be held.

    None for a run that is not lockstep on the inline bus with an in-process controller,
    writes a bus log, trace or truth files, gives no DUT identity with a profile hash, or
    runs in a process with other threads or without ``fork``.
    """
    identity = options.extra_meta.get("dut_identity")
    if (options.bus != "inline" or options.clock != "lockstep"
            or not isinstance(dut, InProcessDut) or options.record_bus or options.save_traces
            or options.csv or not hasattr(os, "fork") or threading.active_count() != 1
            or not isinstance(identity, dict) or not identity.get("profile_sha256")):
        return None
    rest = dataclasses.replace(options, out_dir=None, extra_meta={})
    shape = dataclasses.replace(scenario, name="", description="", events=())
    seed = options.seed if options.seed is not None else scenario.seed
    return (f"{rig_cls.__module__}.{rig_cls.__qualname__}", repr(rest), repr(shape), seed,
            repr(sorted(identity.items())), dut.name,
            f"{type(dut.controller).__module__}.{type(dut.controller).__qualname__}")


def first_event_tick(scenario: Scenario, dt: float, trace_ticks: int) -> int | None:
    """The tick a run of ``scenario`` may be held at, or None.

    Its first event's, when that is a trace tick after the start and before the end.
    """
    if not scenario.events:
        return None
    tick = min(round(e.at_s / dt) for e in scenario.events)
    if tick <= 0 or tick % trace_ticks or tick >= round(scenario.duration_s / dt):
        return None
    return tick


def holder_for(key: tuple[Any, ...] | None, scenario: Scenario, dt: float) -> _Holder | None:
    """A live holder of a run with ``key`` whose prefix ``scenario`` shares, or None.

    ``scenario`` shares it when none of its events comes before the holder's tick.
    """
    if key is None or key not in _holders:
        return None
    holder = _holders[key]
    if any(round(e.at_s / dt) < holder.tick for e in scenario.events):
        return None
    return holder


def hold(key: tuple[Any, ...], tick: int) -> Resume | None:
    """Fork a holder of this run's state at ``tick`` (None in this process, which goes on).

    In a copy resumed from the holder this returns what it is to continue as: the holder
    itself never returns (it exits when this process lets it go or ends).
    """
    if key in _holders or threading.active_count() != 1:
        return None
    if len(_holders) >= MAX_HOLDERS:
        _release(next(iter(_holders)))
    ours, theirs = socket.socketpair()
    pid = os.fork()
    if pid:
        theirs.close()
        _holders[key] = _Holder(pid, ours, tick)
        return None
    ours.close()
    for other in _holders.values():     # only this process's parent may let them go
        other.sock.close()
    _holders.clear()
    return _serve(theirs)


def _serve(sock: socket.socket) -> Resume:
    """The holder: fork a copy per request, wait for it; exit when the requests end."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # the run's process answers Ctrl-C
    global _resumed
    while True:
        try:
            request = _receive(sock)
        except (EOFError, OSError):
            os._exit(0)
        pid = os.fork()
        if pid == 0:
            signal.signal(signal.SIGINT, signal.default_int_handler)
            _resumed = sock
            return request
        _, status = os.waitpid(pid, 0)
        if status != 0:     # it died before it could answer: say so in its place
            try:
                _send(sock, ("error", RuntimeError(
                    f"a run resumed from a checkpoint died (wait status {status})")))
            except OSError:
                os._exit(0)


def resume(holder: _Holder, scenario: Scenario, options: RunOptions) -> RunResult | None:
    """Run ``scenario`` from ``holder``'s checkpoint in a fork of it; its result.

    None when the holder is gone (killed, say): it is let go and the run is the caller's to
    make from the start. Raises what the resumed run raised.
    """
    request = Resume(scenario, options, time.perf_counter(),
                     dt.datetime.now(dt.UTC).isoformat(timespec="seconds"))
    try:
        _send(holder.sock, request)
        kind, *payload = _receive(holder.sock)
    except (OSError, EOFError):
        _drop(holder)
        return None
    except BaseException:       # Ctrl-C while waiting: an answer may come later, unread
        _drop(holder)
        raise
    if kind == "error":
        raise payload[0]
    record, wall_s, sim_s, traces, truth = payload
    result = RunResult(record=record, out_dir=options.out_dir, wall_s=wall_s, sim_s=sim_s)
    result._traces, result._truth = traces, truth
    return result


def resumed() -> bool:
    """True in a copy resumed from a checkpoint (its run's end is :func:`finish`)."""
    return _resumed is not None


def finish(result: RunResult | None, error: BaseException | None = None) -> None:
    """In a resumed copy: send the run's result (or what it raised) back and exit."""
    assert _resumed is not None
    try:
        if error is not None:
            try:
                message: tuple[Any, ...] = ("error", pickle.loads(pickle.dumps(error)))
            except Exception:
                message = ("error", RuntimeError(f"{type(error).__name__}: {error}"))
        else:
            assert result is not None
            message = ("ok", result.record, result.wall_s, result.sim_s, result._traces,
                       result._truth)
        _send(_resumed, message)
    finally:
        os._exit(0)


def _release(key: tuple[Any, ...]) -> None:
    holder = _holders.pop(key)
    holder.sock.close()
    os.waitpid(holder.pid, 0)       # its copies' CPU time counts as this process's children


def _drop(holder: _Holder) -> None:
    """Let a holder that stopped answering go (ended first if it still runs)."""
    for key, held in list(_holders.items()):
        if held is holder:
            del _holders[key]
    holder.sock.close()
    with contextlib.suppress(ProcessLookupError):
        os.kill(holder.pid, signal.SIGKILL)
    with contextlib.suppress(ChildProcessError):
        os.waitpid(holder.pid, 0)


@atexit.register
def release_all() -> None:
    """Let every holder of this process go and wait for it."""
    for key in list(_holders):
        _release(key)


def _send(sock: socket.socket, obj: object) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    sock.sendall(_LEN.pack(len(data)) + data)


def _receive(sock: socket.socket) -> Any:
    (n,) = _LEN.unpack(_exact(sock, _LEN.size))
    return pickle.loads(_exact(sock, n))


def _exact(sock: socket.socket, n: int) -> bytes:
    chunks, left = [], n
    while left:
        chunk = sock.recv(min(left, 1 << 20))
        if not chunk:
            raise EOFError("the other end of a checkpoint closed")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)
