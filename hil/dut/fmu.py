"""DUT profiles of kind ``fmu``: a controller delivered as a Functional Mock-up Unit.

The profile's ``[fmu]`` table::

    [fmu]
    path = "{build_dir}/fmus/agrihil-fertilizer-lsbus.fmu"   # or a path to a delivered .fmu
    level = "bus"                   # "bus": FMI 3.0 + FMI-LS-BUS CAN; "signal": FMI 2.0/3.0
    terminal = "CanChannel"         # bus level: the CAN terminal on the rig's bus (default: the
                                    # FMU's only one)
    bus_notifications = true        # bus level: Can_BusNotifications (confirm, bus errors ...)
    isolation = "process"           # the FMU in a host process of its own (default), or "none"
    host_timeout_s = 10.0           # "process": a host that takes longer on one frame is hung
    [fmu.variables]                 # signal level: FMU variable = rig quantity (or quantity[row])
    "FlowRow1" = "row_flow[1]"

:class:`FmuDut` is :class:`~hil.dut.inprocess.InProcessDut` with the FMU's controller
(:mod:`hil.fmi.bus_node`, :mod:`hil.fmi.signal_node`): on the inline bus in lockstep, or in a
thread on the software bus. With ``[fmu] isolation = "process"`` (the default) that controller
runs in the FMU host, a process of its own stepped in lockstep (:mod:`hil.fmi.host`): an FMU
that crashes, exits or hangs there fails the run as a dying DUT process does, named, with the
run's record and traces written. With ``isolation = "none"`` it runs in the rig's process.
An FMU that fails (an error status, an operation the rig's bus cannot carry) stops the run as
a DUT that raised does, either way.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from hil.dut.base import DutStopped
from hil.dut.fmu_check import Problem, signal_bindings
from hil.dut.fmu_check import check_fmu as _check_fmu
from hil.dut.fmu_check import fmu_problems as _fmu_problems
from hil.dut.fmu_section import FmuSection
from hil.dut.inprocess import Controller, InProcessDut

if TYPE_CHECKING:
    from hil.dut.profile import DutProfile

__all__ = ["FmuDut", "FmuSection", "check_fmu", "fmu_path", "fmu_problems", "make_fmu_dut"]

def fmu_path(profile: DutProfile, build: Path | None = None) -> Path:
    """Where ``[fmu] path`` points (``build``: the build cache entry for ``{build_dir}``).

    Absolute, or relative to the project root when there is such a file, else to the
    profile's directory (as ``wiring.database``).
    """
    from hil.dut.build import build_dir, expand
    from hil.dut.profile import database_path

    section = profile.fmu
    assert section is not None
    if "{build_dir}" in section.path and build is None and profile.build is not None:
        build = build_dir(profile)
    text = expand(section.path, profile, build=build)
    return Path(text) if Path(text).is_absolute() else database_path(text, profile.path)


def fmu_problems(profile: DutProfile, path: Path | None = None) -> list[Problem]:
    """:func:`hil.dut.fmu_check.fmu_problems` of the FMU (default: its ``[fmu] path``)."""
    return _fmu_problems(profile, path or fmu_path(profile))


def check_fmu(profile: DutProfile, path: Path | None = None) -> None:
    """:func:`hil.dut.fmu_check.check_fmu` of the profile's FMU (default: its ``[fmu] path``)."""
    _check_fmu(profile, path or fmu_path(profile))


def make_controller(profile: DutProfile, path: Path) -> Controller:
    """The controller that runs the profile's FMU (checked first)."""
    from hil.contract.codec import ContractCodec
    from hil.contract.registry import rig_contract
    from hil.fmi.bus_node import BusFmuController
    from hil.fmi.fmufile import open_fmu
    from hil.fmi.signal_node import SignalFmuController

    section = profile.fmu
    assert section is not None
    fmu = open_fmu(path)
    period_s = profile.timing.control_period_ms / 1000.0
    if section.level == "bus":
        terminal = next(t for t in fmu.can_terminals
                        if t.name == (section.terminal or fmu.can_terminals[0].name))
        from hil.rig.registry import load_rig

        return BusFmuController(fmu, terminal, period_s=period_s,
                                bus_notifications=section.bus_notifications,
                                parameters=dict(profile.parameters), name=profile.name,
                                bitrate_bps=int(load_rig(profile.dut.rig).bitrate_bps))
    contract = rig_contract(profile.dut.rig, profile.rig_config, str(profile.path or ""))
    inputs, outputs = signal_bindings(profile, fmu, contract)
    return SignalFmuController(
        fmu, ContractCodec.for_contract(contract), inputs=inputs, outputs=outputs,
        period_s=period_s, command_ids=frozenset(profile.wiring.command_ids),
        heartbeat_period_s=profile.timing.heartbeat_period_ms / 1000.0,
        parameters=dict(profile.parameters), name=profile.name)


class FmuDut(InProcessDut):
    """An FMU controller, in its host or in the rig's process; freed on stop and restart."""

    def __init__(self, controller: Controller, factory: Any, *, fmu_file: Path,
                 level: str) -> None:
        super().__init__(controller, factory=factory)
        self.fmu_file = fmu_file
        self.level = level

    @property
    def checkpointable(self) -> bool:
        """Whether a fork of the rig's process holds all of this DUT's state.

        Not with the FMU in its host: a prefix checkpoint would fork the rig without it.
        """
        return not hasattr(self.controller, "host_record")

    def _close(self) -> None:
        close = getattr(self.controller, "close", None)
        if close is not None:
            close()

    def _stopped(self, exc: BaseException) -> DutStopped:
        """A host that died or hung said so itself (a :class:`DutStopped`): kept as it is."""
        if isinstance(exc, DutStopped):
            self._failure = exc
            return DutStopped(exc.what, detail=exc.detail, at_s=exc.at_s)
        return super()._stopped(exc)

    def restart(self, bus_spec: str, env: dict[str, str] | None = None) -> dict[str, Any]:
        """A power cycle: the FMU instance is freed and a new one instantiated."""
        if self._inline:
            self._close()
        return super().restart(bus_spec, env)

    def stop(self, timeout: float = 5.0) -> dict[str, Any]:
        """Stop as an in-process DUT, free the instance; the record keeps the node's bus."""
        result = super().stop(timeout)
        record = getattr(self.controller, "record", None)
        extra: dict[str, Any] = {"fmu": str(self.fmu_file), "fmu_level": self.level}
        node = record() if record is not None else None
        if node is not None:
            extra["lsbus"] = node
        self._close()
        host = getattr(self.controller, "host_record", None)
        extra["fmu_isolation"] = host() if host is not None else {"isolation": "none"}
        return {**result, **extra}

    def identity(self) -> dict[str, Any]:
        """The DUT's name, its FMU file and level."""
        return {"name": self.name, "fmu": str(self.fmu_file), "fmu_level": self.level}


def make_fmu_dut(profile: DutProfile) -> tuple[FmuDut, dict[str, Any]]:
    """Build (when ``[build]`` says how), check and wrap the profile's FMU.

    Returns
    -------
    tuple
        The runner and the build facts for the record.

    Raises
    ------
    ConfigError
        The FMU has problems (:func:`fmu_problems`).
    DutError
        The build failed.
    """
    from hil.dut.build import ensure_built

    build = ensure_built(profile)
    path = fmu_path(profile, Path(str(build["build_dir"])) if build else None)
    check_fmu(profile, path)

    section = profile.fmu
    assert section is not None

    def factory() -> Controller:
        controller = make_controller(profile, path)
        if section.isolation == "none":
            return controller
        from hil.fmi.host import HostedController

        return HostedController(controller, fmu=path, timeout_s=section.host_timeout_s,
                                name=profile.name)

    dut = FmuDut(factory(), factory, fmu_file=path, level=profile.fmu.level)
    dut.name = profile.name
    return dut, build
