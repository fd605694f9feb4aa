"""The FMU host: an FMU in a process of its own, stepped by the rig in lockstep.

An FMU is C code agrihil did not write. Loaded into the rig's process, a segmentation fault,
an ``abort()`` or an ``exit()`` in it ends the rig too, and with it the run's traces and bus
log. :class:`HostedController` runs the FMU's controller (:mod:`hil.fmi.bus_node`,
:mod:`hil.fmi.signal_node`, unchanged) in a child process, the *host*, and is itself the
controller the rig sees: every frame the rig hands it goes down a pipe, the host runs the
controller's ``on_frame`` (its ``doStep`` and event handling) and sends the frames it answers
back; the rig waits for them before it goes on. The same frames in the same order as in the
rig's process, so a lockstep run's bus log is the same byte for byte.

When the host dies (a signal, an exit) or takes longer than ``timeout_s`` to answer one frame
(it is then killed), the call raises :class:`~hil.dut.base.DutStopped` naming the FMU, what
became of its host, the frame it was handling (the n-th SYNC) and what it last wrote on its
standard error, so the run ends as for a dying DUT process: a failed run whose record and
traces are written. An exception in the controller (an FMI error status, an operation the
rig's bus cannot carry) comes back as the same exception with the same text.

How the host is made: the rig's process forks (milliseconds: the child has every module and
the controller object already); the child keeps only its two pipe ends and a pipe for its
standard error, freezes the objects it inherited (no finaliser of the rig's runs in it), ignores
Ctrl-C (the rig answers it), asks the kernel to kill it when the rig's process dies
(:func:`hil.lifetime.die_with_parent`), serves until told to stop and leaves with
``os._exit`` (no ``atexit`` of the rig's). A thread in the rig keeps the tail of the host's
standard error; while a host runs, the rig's process is therefore not single-threaded, which is
what keeps :mod:`hil.rig.checkpoint` from forking it (a fork of the rig would not fork its
FMU). A copy of the rig's process forked anyway refuses to drive a host it did not start.
"""

from __future__ import annotations

import contextlib
import gc
import os
import pickle
import select
import shutil
import signal
import struct
import tempfile
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can

from hil.dut.base import DutStopped
from hil.dut.inprocess import Controller

__all__ = ["HostedController", "decode_frames", "encode_frames"]

SYNC_ID = 0x080
#: lines of the host's standard error kept for the error message
STDERR_LINES = 12

# --- the wire between rig and host -----------------------------------------------------------
# a message: u32 length, then one byte (the operation or the answer's kind) and its payload
_LEN = struct.Struct("<I")
_FRAME = struct.Struct("<IBBHd")     # id, flags, dlc, data length, timestamp
_COUNT = struct.Struct("<H")
_EXT, _RTR, _ERR, _FD, _BRS, _ESI, _RX = 1, 2, 4, 8, 16, 32, 64

OP_START, OP_FRAME, OP_RECORD, OP_CLOSE = b"S", b"F", b"R", b"Q"
#: a frame the controller never answers (its ``silent``): held back and sent with the next
#: request, in order, without an answer of its own
OP_PUSH = b"P"
#: held frames' carrier when there are many (no answer); the most held back at once
OP_FLUSH = b"H"
MAX_HELD = 256
ANS_FRAMES, ANS_VALUE, ANS_RAISED = b"k", b"v", b"x"


def _encode_frame(msg: can.Message) -> bytes:
    data = bytes(msg.data)
    flags = ((_EXT if msg.is_extended_id else 0) | (_RTR if msg.is_remote_frame else 0)
             | (_ERR if msg.is_error_frame else 0) | (_FD if msg.is_fd else 0)
             | (_BRS if msg.bitrate_switch else 0) | (_ESI if msg.error_state_indicator else 0)
             | (_RX if msg.is_rx else 0))
    return _FRAME.pack(msg.arbitration_id, flags, msg.dlc, len(data), msg.timestamp) + data


def _decode_frame(buf: bytes | memoryview, pos: int) -> tuple[can.Message, int]:
    can_id, flags, dlc, size, stamp = _FRAME.unpack_from(buf, pos)
    pos += _FRAME.size
    data = bytes(buf[pos:pos + size])
    msg = can.Message(timestamp=stamp, arbitration_id=can_id, data=data, dlc=dlc,
                      is_extended_id=bool(flags & _EXT), is_remote_frame=bool(flags & _RTR),
                      is_error_frame=bool(flags & _ERR), is_fd=bool(flags & _FD),
                      bitrate_switch=bool(flags & _BRS),
                      error_state_indicator=bool(flags & _ESI), is_rx=bool(flags & _RX),
                      check=False)
    return msg, pos + size


def encode_frames(msgs: list[can.Message]) -> bytes:
    """``msgs`` as the host and the rig exchange them (every field a controller sets)."""
    return _COUNT.pack(len(msgs)) + b"".join(_encode_frame(m) for m in msgs)


def decode_frames(buf: bytes | memoryview) -> list[can.Message]:
    """What :func:`encode_frames` wrote."""
    (count,) = _COUNT.unpack_from(buf, 0)
    pos = _COUNT.size
    out = []
    for _ in range(count):
        msg, pos = _decode_frame(buf, pos)
        out.append(msg)
    return out


def _message(kind: bytes, payload: bytes) -> bytes:
    return _LEN.pack(len(payload) + 1) + kind + payload


def _write(fd: int, kind: bytes, payload: bytes, before: bytes = b"") -> None:
    """One message (after ``before``: messages held back) in as few writes as the pipe takes."""
    data = memoryview(before + _message(kind, payload))
    while data:
        data = data[os.write(fd, data):]


def _read_exact(fd: int, n: int, deadline: float | None,
                poller: select.poll | None) -> bytes | None:
    """``n`` bytes from ``fd``; None at end of file; :class:`TimeoutError` past ``deadline``
    (``poller``: one that polls ``fd``)."""
    chunks: list[bytes] = []
    while n:
        if deadline is not None and poller is not None:
            left = deadline - time.monotonic()
            if left <= 0 or not poller.poll(left * 1000.0):
                raise TimeoutError
        chunk = os.read(fd, n)
        if not chunk:
            return None
        chunks.append(chunk)
        n -= len(chunk)
    return b"".join(chunks)


def _read(fd: int, deadline: float | None = None,
          poller: select.poll | None = None) -> tuple[bytes, bytes] | None:
    head = _read_exact(fd, _LEN.size, deadline, poller)
    if head is None:
        return None
    body = _read_exact(fd, _LEN.unpack(head)[0], deadline, poller)
    if body is None:
        return None
    return body[:1], body[1:]


def _raised(exc: BaseException) -> bytes:
    """An exception as it can cross back (itself when it pickles, else its type and text)."""
    try:
        data = pickle.dumps(exc)
        pickle.loads(data)
        return data
    except Exception:
        return pickle.dumps(("unpicklable", type(exc).__name__, str(exc)))


# --- the host ------------------------------------------------------------------------------------
def _child(controller: Controller, requests: int, answers: int, stderr: int, keep: set[int],
           tmp: str, with_parent: Callable[[], None]) -> int:
    """The host's life after the fork: serve ``controller`` until told to stop."""
    gc.freeze()                      # never finalise what the rig's process left in memory
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    os.dup2(stderr, 2)
    os.dup2(stderr, 1)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    for fd in _open_fds():
        if fd > 2 and fd not in keep:
            with contextlib.suppress(OSError):
                os.close(fd)
    with_parent()
    tempfile.tempdir = tmp           # the FMU's unzipped copy: the rig removes it
    from hil.fmi import instance

    instance.log_sink = lambda line: os.write(2, f"fmu: {line}\n".encode(errors="replace"))
    deferred: BaseException | None = None     # what a pushed frame raised, told next
    while True:
        request = _read(requests)
        if request is None:          # the rig went away
            return 0
        op, payload = request
        if op == OP_PUSH:
            try:
                if controller.on_frame(_decode_frame(payload, 0)[0]) and deferred is None:
                    deferred = RuntimeError("the controller answered a frame it declared "
                                            "silent (FMU host)")
            except BaseException as exc:
                deferred = deferred or exc
            continue
        if op == OP_FLUSH:
            continue
        if deferred is not None and op != OP_CLOSE:
            _write(answers, ANS_RAISED, _raised(deferred))
            deferred = None
            continue
        try:
            if op == OP_FRAME:
                msg, _ = _decode_frame(payload, 0)
                _write(answers, ANS_FRAMES, encode_frames(controller.on_frame(msg)))
            elif op == OP_START:
                controller.configure(pickle.loads(payload))
                _write(answers, ANS_FRAMES, encode_frames(controller.on_start()))
            elif op == OP_RECORD:
                record = getattr(controller, "record", None)
                _write(answers, ANS_VALUE, pickle.dumps(record() if record else None))
            elif op == OP_CLOSE:
                close = getattr(controller, "close", None)
                if close is not None:
                    close()
                user, system = os.times()[:2]
                _write(answers, ANS_VALUE, pickle.dumps({"cpu_s": round(user + system, 3)}))
                return 0
        except BaseException as exc:  # the controller's failure: the rig's to report
            _write(answers, ANS_RAISED, _raised(exc))


def _open_fds() -> list[int]:
    try:
        return [int(name) for name in os.listdir("/proc/self/fd")]
    except OSError:
        return list(range(3, 1024))


def _describe(status: int) -> str:
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        try:
            return f"died of {signal.Signals(sig).name}"
        except ValueError:
            return f"died of signal {sig}"
    return f"exited with exit status {os.WEXITSTATUS(status)}"


class HostedController(Controller):
    """A controller run in the FMU host (see the module's description).

    Parameters
    ----------
    controller : Controller
        The FMU's controller (no instance yet: it instantiates the FMU in ``on_start``, in
        the host).
    fmu : Path
        The FMU file (named in errors).
    timeout_s : float
        How long the host may take to answer one frame before it counts as hung.
    name : str, optional
        The DUT's name.
    """

    def __init__(self, controller: Controller, *, fmu: Path, timeout_s: float,
                 name: str = "fmu") -> None:
        self.inner = controller
        #: the controller's ``silent(msg)``: True for a frame it never answers (a signal-level
        #: FMU's frames but SYNC), which then goes without a round trip
        self._silent: Callable[[can.Message], bool] | None = getattr(controller, "silent",
                                                                     None)
        self.pushed = 0
        self._held: list[bytes] = []
        self.fmu = fmu
        self.timeout_s = timeout_s
        self.name = name
        self.env: dict[str, str] = {}
        self.pid: int | None = None
        self.syncs = 0
        self.calls = 0
        self.cpu_s: float | None = None
        self._last_record: Any = None
        self._requests = self._answers = -1
        self._owner = os.getpid()
        self._tmp: str | None = None
        self._stderr: deque[str] = deque(maxlen=STDERR_LINES)
        self._drain: threading.Thread | None = None
        self._lock = threading.Lock()
        self._poller: select.poll | None = None

    # --- the host's life -----------------------------------------------------------------
    def _spawn(self) -> None:
        from hil.lifetime import die_with_parent

        self._tmp = tempfile.mkdtemp(prefix="agrihil-fmu-host-")
        with_parent = die_with_parent()      # made here: it checks the child's parent is us
        req_r, req_w = os.pipe()
        ans_r, ans_w = os.pipe()
        err_r, err_w = os.pipe()
        pid = os.fork()
        if pid == 0:               # the host
            code = 70
            try:
                code = _child(self.inner, req_r, ans_w, err_w, {req_r, ans_w, err_w},
                              self._tmp, with_parent)
            except BaseException:
                with contextlib.suppress(BaseException):
                    traceback.print_exc()
            finally:
                os._exit(code)
        for fd in (req_r, ans_w, err_w):
            os.close(fd)
        self.pid = pid
        self._held = []
        self._requests, self._answers = req_w, ans_r
        self._poller = select.poll()
        self._poller.register(ans_r, select.POLLIN | select.POLLHUP | select.POLLERR)
        self._stderr.clear()
        self._drain = threading.Thread(target=self._read_stderr, args=(err_r,),
                                       name=f"fmu-host-{pid}-stderr", daemon=True)
        self._drain.start()

    def _read_stderr(self, fd: int) -> None:
        pending = b""
        try:
            while True:
                chunk = os.read(fd, 4096)
                if not chunk:
                    break
                pending += chunk
                *lines, pending = pending.split(b"\n")
                self._stderr.extend(line.decode(errors="replace") for line in lines if line)
                if len(pending) > 4096:
                    self._stderr.append(pending.decode(errors="replace"))
                    pending = b""
        finally:
            if pending:
                self._stderr.append(pending.decode(errors="replace"))
            os.close(fd)

    def _reap(self, *, kill: bool) -> int | None:
        """Wait for the host (killed first with ``kill``); its wait status."""
        pid, self.pid = self.pid, None
        for fd in (self._requests, self._answers):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._requests = self._answers = -1
        self._poller = None
        status = None
        if pid is not None:
            if kill:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
            deadline = time.monotonic() + 2.0
            try:
                while True:
                    done, status = os.waitpid(pid, os.WNOHANG)
                    if done:
                        break
                    if time.monotonic() > deadline:
                        with contextlib.suppress(ProcessLookupError):
                            os.kill(pid, signal.SIGKILL)
                        _, status = os.waitpid(pid, 0)
                        break
                    time.sleep(0.002)
            except ChildProcessError:     # reaped by someone else: its status is gone
                status = None
        if self._drain is not None:
            self._drain.join(1.0)
            self._drain = None
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None
        return status

    # --- one request ---------------------------------------------------------------------
    def _doing(self, op: bytes, msg: can.Message | None) -> str:
        if op == OP_START:
            return "starting (instantiating and initialising the FMU)"
        if op == OP_FRAME and msg is not None:
            if not msg.is_extended_id and msg.arbitration_id == SYNC_ID:
                return f"handling SYNC {self.syncs}"
            kind = "error frame" if msg.is_error_frame else f"frame 0x{msg.arbitration_id:X}"
            return f"handling the {kind} after SYNC {self.syncs}"
        return "answering the rig"

    def _said(self) -> str:
        lines = list(self._stderr)
        return f"its last output: {' | '.join(lines)}" if lines else ""

    def _call(self, op: bytes, payload: bytes, msg: can.Message | None = None
              ) -> tuple[bytes, bytes]:
        if os.getpid() != self._owner:
            raise DutStopped(f"cannot be driven from a copy of the rig's process: the host "
                             f"of FMU {self.fmu.name} belongs to process {self._owner}")
        if self.pid is None:
            raise DutStopped(f"has no host process for FMU {self.fmu.name} (it stopped "
                             f"before)")
        doing = self._doing(op, msg)
        self.calls += 1
        if op == OP_PUSH:
            self._held.append(_message(op, payload))
            if len(self._held) < MAX_HELD:
                return ANS_FRAMES, _COUNT.pack(0)
            op, payload = OP_FLUSH, b""          # a long run of them: sent on their own
        held, self._held = b"".join(self._held), []
        try:
            _write(self._requests, op, payload, held)
            if op == OP_FLUSH:
                return ANS_FRAMES, _COUNT.pack(0)
            answer = _read(self._answers, time.monotonic() + self.timeout_s, self._poller)
        except TimeoutError:
            self._reap(kill=True)
            raise DutStopped(f"stopped answering: FMU {self.fmu.name} took more than "
                             f"{self.timeout_s:g} s {doing} (its host process was killed)",
                             detail=self._said()) from None
        except (BrokenPipeError, OSError):
            answer = None
        if answer is None:
            status = self._reap(kill=False)
            how = _describe(status) if status is not None else "ended"
            raise DutStopped(f"crashed: the host process of FMU {self.fmu.name} {how} "
                             f"{doing}", detail=self._said())
        return answer

    def _frames(self, op: bytes, payload: bytes, msg: can.Message | None = None
                ) -> list[can.Message]:
        with self._lock:
            kind, body = self._call(op, payload, msg)
        if kind == ANS_RAISED:
            raise _exception(body)
        return decode_frames(body)

    # --- the controller ------------------------------------------------------------------
    def configure(self, env: dict[str, str]) -> None:
        """Kept for the host, which configures the controller when it starts."""
        self.env = dict(env)

    def on_start(self) -> list[can.Message]:
        """Start a host (a fresh one: a power cycle is a new process) and the FMU in it."""
        self.close()
        self.syncs = 0
        self._spawn()
        return self._frames(OP_START, pickle.dumps(self.env))

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        if not msg.is_extended_id and msg.arbitration_id == SYNC_ID and \
                not msg.is_error_frame:
            self.syncs += 1
        silent = self._silent is not None and self._silent(msg)
        self.pushed += silent
        return self._frames(OP_PUSH if silent else OP_FRAME, _encode_frame(msg), msg)

    def record(self) -> Any:
        """The controller's record (the node's bus at bus level), as the host last gave it."""
        if self.pid is not None and self._lock.acquire(timeout=self.timeout_s):
            try:
                kind, body = self._call(OP_RECORD, b"")
                if kind == ANS_VALUE:
                    self._last_record = pickle.loads(body)
            except DutStopped:
                pass
            finally:
                self._lock.release()
        return self._last_record

    def host_record(self) -> dict[str, Any]:
        """What the run's record keeps of the host."""
        return {"isolation": "process", "calls": self.calls,
                "round_trips": self.calls - self.pushed, "cpu_s": self.cpu_s,
                "timeout_s": self.timeout_s}

    def close(self) -> None:
        """Free the FMU instance and end the host (killed when it does not answer)."""
        if self.pid is None:
            return
        if not self._lock.acquire(timeout=self.timeout_s):
            self._reap(kill=True)
            return
        try:
            kind, body = self._call(OP_CLOSE, b"")
            if kind == ANS_VALUE:
                self.cpu_s = pickle.loads(body).get("cpu_s")
            self._reap(kill=False)
        except DutStopped:
            pass
        finally:
            self._lock.release()


def _exception(body: bytes) -> BaseException:
    """The controller's exception as the host sent it."""
    value = pickle.loads(body)
    if isinstance(value, BaseException):
        return value
    from hil.fmi.instance import FmuCallError

    _, name, text = value
    return FmuCallError(f"{name}: {text}")

