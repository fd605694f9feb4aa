"""The DUT runner interface: start on a bus spec, report health, stop cleanly."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

from hil.errors import HilError


class DutError(HilError, RuntimeError):
    """The DUT crashed, hung, or could not be started."""


class DutSetupError(DutError):
    """The DUT could not be started at all (its command cannot be executed): a setup error,
    not a DUT failure.
    """


class DutStopped(DutError):
    """The DUT stopped during a run: it exited (any status), died of a signal, raised, or
    stopped answering. ``what`` says how ("exited with SIGSEGV"); the runner adds when.
    """

    def __init__(self, what: str, *, detail: str = "", at_s: float | None = None) -> None:
        self.what = what
        self.detail = detail
        #: when it stopped (simulated time), when known better than "now"
        self.at_s = at_s
        super().__init__(f"the DUT {what}" + (f"; {detail}" if detail else ""))


class DutRunner(ABC):
    """Runs one controller under test for the length of a run."""

    name: str = "dut"

    @abstractmethod
    def start(self, bus_spec: str, env: dict[str, str] | None = None) -> None:
        """Start the DUT connected to ``bus_spec``; return when it is on the bus.

        ``env``: what the rig offers besides the bus (e.g. ``AGRIHIL_GNSS_PORT``).
        """

    @abstractmethod
    def stop(self, timeout: float = 5.0) -> dict[str, Any]:
        """Stop the DUT (safe to call twice); returns what the record should keep of it."""

    def restart(self, bus_spec: str, env: dict[str, str] | None = None) -> dict[str, Any]:
        """Stop the DUT and start it again, as a power cycle would; returns what :meth:`stop`
        said of the run before the restart.
        """
        before = self.stop()
        self.start(bus_spec, env)
        return before

    @abstractmethod
    def check(self) -> None:
        """Raise :class:`DutError` if the DUT has died."""

    def identity(self) -> dict[str, Any]:
        return {"name": self.name}
