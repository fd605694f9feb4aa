"""The DUT profile's ``[fmu]`` table (kind ``fmu``); what is done with it: :mod:`hil.dut.fmu`.

A module of its own, importing nothing of :mod:`hil.dut`, so that the profile loader can
declare the table without importing the FMU runner (which imports the build, which imports the
profile).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from hil.errors import ConfigError
from hil.validation import Range, check_value

__all__ = ["FmuSection", "Level"]

Level = Literal["bus", "signal"]
Isolation = Literal["process", "none"]
#: ``host_timeout_s``'s range (kept here: the schema's fuzz test builds a daemon profile, which
#: has no [fmu] table to put it in)
HOST_TIMEOUT = Range("float", 0, 3600, low_open=True, unit="s",
                     why="a frame an FMU takes an hour on is a hung FMU")


@dataclass(frozen=True)
class FmuSection:
    """The profile's ``[fmu]`` table (kind ``fmu`` only).

    Parameters
    ----------
    path : str
        The FMU: absolute, relative to the project root or the profile, or in the build cache
        (``{build_dir}``, with a ``[build]`` section that makes it).
    level : {"bus", "signal"}
        ``bus``: an FMI 3.0 FMU with an FMI-LS-BUS CAN terminal; ``signal``: an FMI 2.0 or 3.0
        FMU whose variables the profile binds to rig quantities.
    terminal : str, optional
        The CAN terminal wired to the rig's bus (default: the FMU's only CAN terminal).
    bus_notifications : bool, optional
        ``Can_BusNotifications`` for an FMU that declares it.
    variables : dict of str to str, optional
        Signal level: FMU variable name → rig quantity (``quantity`` or ``quantity[row]``).
    waive_validation : tuple of str, optional
        fmpy's validation problems the profile accepts, each by the start of its text (an
        FMU from elsewhere whose description fmpy judges stricter than its tools did); every
        other problem refuses the FMU. Say why in a comment beside it.
    isolation : {"process", "none"}, optional
        ``process`` (the default): the FMU runs in a host process of its own, stepped in
        lockstep, so that a crash, an exit or a hang in its code fails the run as a dying
        DUT does; ``none``: in the rig's process (a crash there ends the rig's process and
        the run's traces with it).
    host_timeout_s : float, optional
        ``isolation = "process"``: how long the FMU's host may take to answer one frame (its
        ``doStep`` and event handling) before the FMU counts as hung and its host is killed
        (0 < s <= 3600, default 10).
    """

    path: str
    level: Level
    terminal: str = ""
    bus_notifications: bool = True
    variables: dict[str, str] = field(default_factory=dict)
    waive_validation: tuple[str, ...] = ()
    isolation: Isolation = "process"
    host_timeout_s: float = 10.0

    def __post_init__(self) -> None:
        try:
            check_value(self.host_timeout_s, HOST_TIMEOUT, what="host_timeout_s")
        except ValueError as exc:
            raise ConfigError(str(exc), key="host_timeout_s") from None
        if not self.path:
            raise ValueError("path must name the FMU")
        if self.level == "bus" and self.variables:
            raise ValueError("variables bind a signal-level FMU; a bus-level FMU speaks "
                             "frames (remove [fmu.variables] or set level = \"signal\")")
