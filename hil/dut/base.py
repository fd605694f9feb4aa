"""The DUT runner interface: start on a bus spec, report health, stop cleanly."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

from hil.errors import HilError


class DutError(HilError, RuntimeError):
    """The DUT crashed, hung, or could not be started."""


class DutSetupError(DutError):
    """The DUT could not be started at all (its command cannot be executed).

    A setup error, not a DUT failure.
    """


class DutStopped(DutError):
    """The DUT stopped during a run: it exited, died of a signal, raised, or went silent.

    Parameters
    ----------
    what : str
        How it stopped ("exited with SIGSEGV"); the runner adds when.
    detail : str, optional
        More about it (the end of its stderr, say).
    at_s : float, optional
        When it stopped (simulated time), when known better than "now".
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

        Parameters
        ----------
        bus_spec : str
            The bus to join (:func:`hil.bus.open_bus` spec).
        env : dict of str to str, optional
            What the rig offers besides the bus (e.g. ``AGRIHIL_GNSS_PORT``).

        Raises
        ------
        DutSetupError
            The DUT cannot be started at all.
        DutStopped
            It died or stayed silent while coming up.
        """

    @abstractmethod
    def stop(self, timeout: float = 5.0) -> dict[str, Any]:
        """Stop the DUT (safe to call twice); returns what the record should keep of it."""

    def restart(self, bus_spec: str, env: dict[str, str] | None = None) -> dict[str, Any]:
        """Stop the DUT and start it again, as a power cycle would.

        Parameters
        ----------
        bus_spec : str
            The bus to join again.
        env : dict of str to str, optional
            As for :meth:`start`.

        Returns
        -------
        dict
            What :meth:`stop` said of the run before the restart.
        """
        before = self.stop()
        self.start(bus_spec, env)
        return before

    @abstractmethod
    def check(self) -> None:
        """Raise :class:`DutError` if the DUT has died."""

    def identity(self) -> dict[str, Any]:
        """The DUT's identity for the record (at least its ``name``)."""
        return {"name": self.name}
