"""From a DUT profile to the runner that runs it for one scenario."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from hil.dut.base import DutRunner
from hil.dut.build import ensure_built
from hil.dut.inprocess import Controller, InProcessDut
from hil.dut.physical import PhysicalDut
from hil.dut.process import ProcessDut
from hil.dut.profile import DutProfile
from hil.errors import ConfigError


def load_controller(profile: DutProfile) -> Controller:
    """Instantiate ``launch.inprocess`` ("module:Class") with the profile's parameters."""
    target = profile.launch.inprocess
    module_name, _, attr = target.partition(":")
    where = {"path": str(profile.path), "key": "launch.inprocess"}
    try:
        cls = getattr(importlib.import_module(module_name), attr)
    except (ImportError, AttributeError) as exc:
        raise ConfigError(f"cannot load {target!r}: {exc}", **where) from exc
    try:
        controller = cls(**dict(profile.parameters))
    except TypeError as exc:
        raise ConfigError(f"{target} rejects the parameters: {exc}", path=str(profile.path),
                          key="parameters") from exc
    except ValueError as exc:
        raise ConfigError(str(exc), path=str(profile.path), key="parameters") from exc
    if not isinstance(controller, Controller):
        raise ConfigError(f"{target} is not a hil.dut.Controller", **where)
    return controller


#: bus specs whose frames never leave the rig's process: a DUT in another process cannot join
IN_PROCESS_BUSES = ("virtual", "inline")


def in_process_bus(bus: str) -> bool:
    """True for a bus spec that exists only inside the rig's process."""
    return bus in IN_PROCESS_BUSES or bus.startswith(("virtual:", "virtual,"))


def check_bus_for_dut(bus: str, dut_kind: str, *, inprocess_twin: bool = False) -> None:
    """Refuse a bus a DUT of ``dut_kind`` cannot join, naming the buses that work.

    Parameters
    ----------
    bus : str
        The ``--bus`` spec.
    dut_kind : str
        The profile's ``dut.kind`` (``firmware``, ``daemon``, ``inprocess``, ``physical``,
        ``fmu``).
    inprocess_twin : bool
        The profile names an in-process twin (``launch.inprocess``): a daemon then runs on
        ``inline`` in-process.

    Raises
    ------
    ConfigError
        The bus lives inside the rig's process and the DUT does not.
    """
    if not in_process_bus(bus) or dut_kind in ("inprocess", "fmu"):
        return
    if bus == "inline" and inprocess_twin and dut_kind == "daemon":
        return
    works = "softbus (the default), socketcand:HOST:PORT/CH, socketcan:IFACE"
    raise ConfigError(f"{bus} lives inside the rig's process, and a {dut_kind} DUT runs "
                      f"in a process of its own (or on its own hardware): use {works}",
                      key="--bus")


def runs_inprocess(profile: DutProfile, bus: str) -> bool:
    """In-process DUTs and FMUs always; daemons with a twin on the inline bus (lockstep)."""
    kind = profile.dut.kind
    return kind in ("inprocess", "fmu") or (bus == "inline" and bool(profile.launch.inprocess)
                                   and kind == "daemon")


def make_dut(profile: DutProfile, *, bus: str, clock: str,
             log_dir: Path | None = None) -> tuple[DutRunner, dict[str, Any]]:
    """The runner for ``profile`` on ``bus``/``clock``, and build facts for the record."""
    if profile.dut.kind == "fmu":
        from hil.dut.fmu import make_fmu_dut

        return make_fmu_dut(profile)
    if runs_inprocess(profile, bus):
        dut = InProcessDut(load_controller(profile), factory=lambda: load_controller(profile))
        dut.name = profile.name
        return dut, {}
    # before anything is built or started: a process on an in-process bus only times out
    check_bus_for_dut(bus, profile.dut.kind, inprocess_twin=bool(profile.launch.inprocess))
    if profile.dut.kind == "physical":
        return PhysicalDut(profile), {}
    build = ensure_built(profile)
    build_path = Path(str(build["build_dir"])) if build else None
    return ProcessDut(profile, clock=clock, log_dir=log_dir, build=build_path), build


def profile_run_options(profile: DutProfile, *, rig_from: DutProfile | None = None
                        ) -> dict[str, Any]:
    """What every run of ``profile`` takes from it besides the DUT runner.

    Parameters
    ----------
    profile : DutProfile
        The DUT to run.
    rig_from : DutProfile, optional
        The profile whose ``[rig]`` overrides configure the rig (default: ``profile``; a
        baseline DUT runs on the plant of the DUT it is compared with, but on its own
        ``wiring``: the DUT's binding is the DUT's bus, not the baseline's).

    Returns
    -------
    dict
        :class:`hil.rig.RunOptions` fields: the rig's config overrides and their source, the
        flood limit (``timing.max_frames_per_period`` of ``profile``) and its
        ``wiring.command_ids`` (checked during the run against what the DUT configures).
    """
    rig = rig_from or profile
    config = dict(rig.rig_config)
    if rig is not profile:
        # the plant is the compared DUT's, the bus between rig and DUT is the one that runs:
        # a baseline speaks its own database, whatever binding the DUT brought
        config.pop("wiring", None)
        if "wiring" in profile.rig_config:
            config["wiring"] = profile.rig_config["wiring"]
    return {"rig_config": config, "rig_config_source": str(rig.path or ""),
            "max_dut_frames_per_period": profile.timing.max_frames_per_period,
            "command_ids": frozenset(profile.wiring.command_ids),
            "command_ids_source": str(profile.path or "")}
