"""The DUT profile's ``[fmu]`` table (kind ``fmu``); what is done with it: :mod:`hil.dut.fmu`.

A module of its own, importing nothing of :mod:`hil.dut`, so that the profile loader can
declare the table without importing the FMU runner (which imports the build, which imports the
profile).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

__all__ = ["FmuSection", "Level"]

Level = Literal["bus", "signal"]


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
    """

    path: str
    level: Level
    terminal: str = ""
    bus_notifications: bool = True
    variables: dict[str, str] = field(default_factory=dict)
    waive_validation: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.path:
            raise ValueError("path must name the FMU")
        if self.level == "bus" and self.variables:
            raise ValueError("variables bind a signal-level FMU; a bus-level FMU speaks "
                             "frames (remove [fmu.variables] or set level = \"signal\")")
