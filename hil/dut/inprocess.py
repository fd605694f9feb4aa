"""A Python controller running in a thread of the rig's process, on its own bus handle.

The fastest way to run a DUT in lockstep: no process start-up, frames still cross a real
python-can bus (``virtual`` or the software bus), so the controller reads and writes exactly
the frames a firmware would.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import can

from hil.bus import open_bus
from hil.bus.inline import InlineBus
from hil.dut.base import DutError, DutRunner, DutStopped


class Controller(ABC):
    """A controller as the rig sees it: frames in, frames out."""

    name: str = "controller"

    @abstractmethod
    def on_frame(self, msg: can.Message) -> list[can.Message]:
        """Handle one received frame; return the frames to send in answer."""

    def configure(self, env: dict[str, str]) -> None:
        """What the rig offers besides the bus (a serial port's path, say)."""
        return None

    def on_start(self) -> list[can.Message]:
        """Frames to send once on joining the bus (boot-up, say)."""
        return []


class InProcessDut(DutRunner):
    """Runs a :class:`Controller` in the rig's process: in a thread with its own bus, or inline.

    Parameters
    ----------
    controller : Controller
        The controller under test.
    factory : callable, optional
        Builds a fresh controller for :meth:`restart` (its state is lost, as on power-up);
        without one the DUT cannot restart.
    """

    def __init__(self, controller: Controller,
                 factory: Callable[[], Controller] | None = None) -> None:
        self.controller = controller
        #: builds a fresh controller for :meth:`restart` (its state is lost, as on power-up)
        self.factory = factory
        self._inline_bus: InlineBus | None = None
        self.restarts = 0
        self.name = controller.name
        self._bus: can.BusABC | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._failure: BaseException | None = None
        self.frames_in = 0
        self.frames_out = 0
        self._inline = False

    def _stopped(self, exc: BaseException) -> DutStopped:
        """What the run reports of a controller that raised.

        Any exception counts, ``SystemExit`` (``sys.exit(0)`` too) included: a controller has no
        business ending the process.
        """
        self._failure = exc
        what = (f"exited (SystemExit({exc.code!r}) in-process)" if isinstance(exc, SystemExit)
                else f"raised {type(exc).__name__}: {exc}")
        return DutStopped(what)

    def _guarded(self, call: Callable[[], Any]) -> Any:
        try:
            return call()
        except KeyboardInterrupt:
            raise
        except BaseException as exc:   # the DUT failed: reported as such
            raise self._stopped(exc) from exc

    def attach_inline(self, env: dict[str, str] | None = None) -> InlineBus:
        """Run without a thread: the rig's bus calls the controller directly (lockstep)."""
        self._guarded(lambda: self.controller.configure(env or {}))
        first = self._guarded(self.controller.on_start)
        bus = InlineBus(self._inline_frame)
        bus.inject(first)
        self._inline = True
        self._inline_bus = bus
        return bus

    def restart(self, bus_spec: str, env: dict[str, str] | None = None) -> dict[str, Any]:
        """Replace the controller with a fresh one from :attr:`factory`.

        On the inline bus there is no thread to stop: the new controller's start-up frames are
        injected at once.

        Returns
        -------
        dict
            What :meth:`stop` said of the run before the restart (inline: the name, kind and the
            number of restarts).

        Raises
        ------
        DutError
            The DUT was built without a factory.
        DutStopped
            The factory or the new controller's start-up raised.
        """
        if self.factory is None:
            raise DutError(f"in-process controller {self.name!r} cannot restart: it was "
                           f"built without a factory")
        if not self._inline:
            before = self.stop()
            self._stop = threading.Event()
            self.controller = self.factory()
            self.restarts += 1
            self.start(bus_spec, env)
            return before
        self.controller = self._guarded(self.factory)
        self._guarded(lambda: self.controller.configure(env or {}))
        assert self._inline_bus is not None
        self._inline_bus.inject(self._guarded(self.controller.on_start))
        self.restarts += 1
        return {"name": self.name, "kind": "in-process inline", "restarts": self.restarts}

    def _inline_frame(self, msg: can.Message) -> list[can.Message]:
        self.frames_in += 1
        try:
            out = self.controller.on_frame(msg)
        except KeyboardInterrupt:
            raise
        except BaseException as exc:   # SystemExit too: the DUT stopped
            raise self._stopped(exc) from exc
        self.frames_out += len(out)
        return out

    def start(self, bus_spec: str, env: dict[str, str] | None = None) -> None:
        """Configure the controller, join the bus, send its start-up frames and start its thread.

        Parameters
        ----------
        bus_spec : str
            The bus to join.
        env : dict of str to str, optional
            What the rig offers besides the bus.

        Raises
        ------
        DutStopped
            The controller raised while configuring or starting.
        """
        self._guarded(lambda: self.controller.configure(env or {}))
        self._bus = open_bus(bus_spec)
        for msg in self._guarded(self.controller.on_start):
            self._bus.send(msg)
        self._thread = threading.Thread(target=self._run, name=f"dut-{self.name}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        assert self._bus is not None
        try:
            while not self._stop.is_set():
                msg = self._bus.recv(0.05)
                if msg is None:
                    continue
                self.frames_in += 1
                for out in self.controller.on_frame(msg):
                    self._bus.send(out)
                    self.frames_out += 1
        except BaseException as exc:  # reported through check() and stop(), never silent
            self._failure = exc

    def check(self) -> None:
        """Raise :class:`~hil.dut.base.DutStopped` if the controller has raised."""
        if self._failure is not None:
            raise self._stopped(self._failure) from self._failure

    def stop(self, timeout: float = 5.0) -> dict[str, Any]:
        """Stop the thread and leave the bus; return frame counts and any failure for the record.

        Parameters
        ----------
        timeout : float, optional
            How long to wait for the thread, in seconds; a thread still alive is reported ``hung``.

        Returns
        -------
        dict
            Name, kind, restarts, frames in and out, whether it hung, and its failure (or None).
        """
        self._stop.set()
        alive = False
        if self._thread is not None:
            self._thread.join(timeout)
            alive = self._thread.is_alive()
            self._thread = None
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None
        kind = "in-process inline" if self._inline else "in-process"
        return {"name": self.name, "kind": kind, "restarts": self.restarts,
                "frames_in": self.frames_in,
                "frames_out": self.frames_out, "hung": alive,
                "failure": None if self._failure is None else repr(self._failure)}
