"""DUT profiles of kind ``fmu``: a controller delivered as a Functional Mock-up Unit.

The profile's ``[fmu]`` table::

    [fmu]
    path = "{build_dir}/fmus/agrihil-fertilizer-lsbus.fmu"   # or a path to a delivered .fmu
    level = "bus"                   # "bus": FMI 3.0 + FMI-LS-BUS CAN; "signal": FMI 2.0/3.0
    terminal = "CanChannel"         # bus level: the CAN terminal on the rig's bus (default: the
                                    # FMU's only one)
    bus_notifications = true        # bus level: Can_BusNotifications (confirm, bus errors ...)
    [fmu.variables]                 # signal level: FMU variable = rig quantity (or quantity[row])
    "FlowRow1" = "row_flow[1]"

The FMU runs in the rig's process (no process boundary): on the inline bus in lockstep, or in a
thread on the software bus; :class:`FmuDut` is :class:`~hil.dut.inprocess.InProcessDut` with
the FMU's controller (:mod:`hil.fmi.bus_node`, :mod:`hil.fmi.signal_node`). An FMU that fails
(an error status, an operation the rig's bus cannot carry) stops the run as a DUT that raised
does; one that crashes the process is that run's (or campaign sample's) error, as a dying
DUT is.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from hil.dut.fmu_section import FmuSection
from hil.dut.inprocess import Controller, InProcessDut
from hil.errors import ConfigError

if TYPE_CHECKING:
    from hil.dut.profile import DutProfile
    from hil.fmi.fmufile import FmuFile

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


Problem = tuple[str, str, str]   # key, message, fix


def _bus_problems(profile: DutProfile, fmu: FmuFile) -> list[Problem]:
    section = profile.fmu
    assert section is not None
    out: list[Problem] = []
    if fmu.fmi_major != 3:
        return [("fmu.level", f"a bus-level FMU is FMI 3.0 (FMI-LS-BUS); this one is FMI "
                              f"{fmu.description.fmiVersion}", "level = \"signal\"")]
    if not fmu.description.coSimulation.hasEventMode:
        out.append(("fmu.path", "the FMU has no event mode (hasEventMode): LS-BUS needs it to "
                                "hand frames over with clocks", ""))
    if not fmu.can_terminals:
        out.append(("fmu.path", "the FMU declares no CAN terminal (terminalsAndIcons.xml: a "
                                "terminal of kind org.fmi-ls-bus.network-terminal whose "
                                "Rx_Data/Tx_Data are LS-BUS CAN binaries)",
                    "a bus-level FMU needs one; a signal-level one: level = \"signal\""))
        return out
    names = [t.name for t in fmu.can_terminals]
    chosen = section.terminal or (names[0] if len(names) == 1 else "")
    if section.terminal and section.terminal not in names:
        out.append(("fmu.terminal", f"the FMU has no CAN terminal {section.terminal!r} (its "
                                    f"CAN terminals: {', '.join(names)})", ""))
    unbound = [n for n in names if n != chosen] + list(fmu.other_terminals)
    if unbound:
        out.append(("fmu.terminal", f"the FMU declares {len(names) + len(fmu.other_terminals)}"
                                    f" terminals and the profile binds "
                                    f"{'one' if chosen else 'none'}"
                                    f"{f' ({chosen})' if chosen else ''}: "
                                    f"{', '.join(unbound)} would be left unconnected (the rig "
                                    f"has one CAN bus)",
                    "an FMU with one CAN terminal, or terminal = the one to wire"))
    if not fmu.ls_bus:
        out.append(("fmu.path", "the FMU ships no FMI-LS-BUS manifest "
                                "(extra/org.fmi-standard.fmi-ls-bus/fmi-ls-manifest.xml)", ""))
    return out


def signal_bindings(profile: DutProfile, fmu: FmuFile, contract: Any,
                    problems: list[Problem] | None = None) -> tuple[list[Any], list[Any]]:
    """The profile's ``[fmu.variables]`` as input and output bindings (problems appended)."""
    from hil.contract.units import dimension, factor
    from hil.fmi.signal_node import SignalBinding, parse_quantity, variable_unit

    section = profile.fmu
    assert section is not None
    bad = problems if problems is not None else []
    inputs: list[Any] = []
    outputs: list[Any] = []
    for name, text in section.variables.items():
        key = f"fmu.variables.{name}"
        var = fmu.variable(name)
        if var is None:
            bad.append((key, f"the FMU has no variable {name!r}", ""))
            continue
        try:
            quantity, row = parse_quantity(text, contract)
        except ConfigError as exc:
            bad.append((key, str(exc), ""))
            continue
        want = {"input": "to_dut", "output": "from_dut"}.get(var.causality)
        if want is None:
            bad.append((key, f"{name} is a {var.causality} of the FMU: only inputs and "
                             f"outputs are bound", ""))
            continue
        if quantity.direction != want:
            side = "the rig sends" if quantity.direction == "to_dut" else "the DUT sends"
            bad.append((key, f"{name} is an FMU {var.causality} and {quantity.name} is a "
                             f"quantity {side}", ""))
            continue
        unit = variable_unit(var)
        if not unit and (quantity.kind in ("flag", "enum", "counter")
                         or dimension(quantity.unit) in ("count", "dimensionless")):
            f = 1.0   # a count (rows, pulses) in an integer, which FMI 2.0 gives no unit
        else:
            if not unit and quantity.unit:
                bad.append((key, f"{name} declares no unit and {quantity.name} is in "
                                 f"{quantity.unit!r}: the unit cannot be checked",
                            f"unit=\"{quantity.unit}\" on the variable (or its type)"))
                continue
            try:
                f = factor(quantity.unit, unit)
            except ConfigError as exc:
                bad.append((key, f"{name} is in {unit!r}, {quantity.name} in "
                                 f"{quantity.unit!r}: {str(exc).split('] ', 1)[-1]}", ""))
                continue
        binding = SignalBinding(var, quantity, row, f)
        (inputs if want == "to_dut" else outputs).append(binding)
    return inputs, outputs


def _signal_problems(profile: DutProfile, fmu: FmuFile) -> list[Problem]:
    from hil.contract.codec import ContractCodec
    from hil.contract.registry import rig_contract

    out: list[Problem] = []
    if fmu.can_terminals:
        out.append(("fmu.level", f"the FMU has CAN terminals "
                                 f"({', '.join(t.name for t in fmu.can_terminals)}): it speaks "
                                 f"frames", "level = \"bus\""))
        return out
    try:
        contract = rig_contract(profile.dut.rig, profile.rig_config, str(profile.path or ""))
        codec = ContractCodec.for_contract(contract)
    except ConfigError as exc:
        return [("wiring.binding", str(exc), "")]
    inputs, outputs = signal_bindings(profile, fmu, contract, out)
    bound = {b.variable.name for b in (*inputs, *outputs)}
    for var in fmu.variables.values():
        if var.causality == "input" and var.name not in bound:
            out.append((f"fmu.variables.{var.name}",
                        f"FMU input {var.name} is bound to no rig quantity (it would keep its "
                        f"start value for the whole run)",
                        f"\"{var.name}\" = \"<quantity>\" under [fmu.variables]"))
    for b in (*inputs, *outputs):
        if not codec.carries(b.quantity.name):
            out.append((f"fmu.variables.{b.variable.name}",
                        f"the binding in force carries no frame for {b.quantity.name}",
                        "bind it in [wiring] binding, or bind the variable to another "
                        "quantity"))
    if not outputs:
        out.append(("fmu.variables", "no FMU output is bound: the DUT would command nothing",
                    ""))
    return out


def fmu_problems(profile: DutProfile, path: Path | None = None) -> list[Problem]:
    """Everything wrong with the profile's FMU, every problem at once.

    fmpy's validation, its interface, terminals, bindings and parameters: ``(key, message,
    fix)`` each.
    """
    from hil.fmi.fmufile import open_fmu, validate
    from hil.fmi.parameters import parameter_problems

    section = profile.fmu
    if section is None:
        return [("fmu", "a DUT of kind fmu needs an [fmu] section", "")]
    target = path or fmu_path(profile)
    if not target.exists():
        return [("fmu.path", f"the FMU {target} does not exist", "")]
    try:
        fmu = open_fmu(target)
    except ConfigError as exc:
        return [("fmu.path", str(exc).split(": ", 1)[-1] if exc.path else str(exc), "")]
    out: list[Problem] = [("fmu.path", f"fmpy's validation: {p}",
                           "fix the FMU, or accept it: waive_validation = [\"<its start>\"]")
                          for p in validate(target)
                          if not any(p.startswith(w) for w in section.waive_validation)]
    if section.level == "bus":
        out += _bus_problems(profile, fmu)
    else:
        out += _signal_problems(profile, fmu)
    out += [(key, msg, "") for key, msg in parameter_problems(fmu, dict(profile.parameters))]
    return out


def check_fmu(profile: DutProfile, path: Path | None = None) -> None:
    """Refuse the profile's FMU when :func:`fmu_problems` finds anything.

    Raises
    ------
    ConfigError
        Naming the profile, the first problem's key and how many more there are.
    """
    problems = fmu_problems(profile, path)
    if not problems:
        return
    key, message, fix = problems[0]
    more = f"; and {len(problems) - 1} more problem(s)" if len(problems) > 1 else ""
    raise ConfigError(f"{message}{f' (fix: {fix})' if fix else ''}{more}",
                      path=str(profile.path or ""), key=key)


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
        return BusFmuController(fmu, terminal, period_s=period_s,
                                bus_notifications=section.bus_notifications,
                                parameters=dict(profile.parameters), name=profile.name)
    contract = rig_contract(profile.dut.rig, profile.rig_config, str(profile.path or ""))
    inputs, outputs = signal_bindings(profile, fmu, contract)
    return SignalFmuController(
        fmu, ContractCodec.for_contract(contract), inputs=inputs, outputs=outputs,
        period_s=period_s, command_ids=frozenset(profile.wiring.command_ids),
        heartbeat_period_s=profile.timing.heartbeat_period_ms / 1000.0,
        parameters=dict(profile.parameters), name=profile.name)


class FmuDut(InProcessDut):
    """An FMU controller in the rig's process; its instance is freed on stop and restart."""

    def __init__(self, controller: Controller, factory: Any, *, fmu_file: Path,
                 level: str) -> None:
        super().__init__(controller, factory=factory)
        self.fmu_file = fmu_file
        self.level = level

    def _close(self) -> None:
        close = getattr(self.controller, "close", None)
        if close is not None:
            close()

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
        if record is not None:
            extra["lsbus"] = record()
        self._close()
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

    def factory() -> Controller:
        return make_controller(profile, path)

    assert profile.fmu is not None
    dut = FmuDut(factory(), factory, fmu_file=path, level=profile.fmu.level)
    dut.name = profile.name
    return dut, build
