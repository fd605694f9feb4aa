"""What is wrong with a DUT profile's FMU, every problem at once (kind ``fmu``).

fmpy's validation, the FMU's interface and terminals (bus level), the bindings of its variables
to rig quantities with their units (signal level), its parameters. A module of its own that
imports neither the profile loader nor the build (both use it: the loader refuses a profile
whose FMU has problems, so ``hil profile check`` and every run do, without an import circle).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hil.errors import ConfigError

__all__ = ["Problem", "check_fmu", "fmu_problems", "signal_bindings"]

Problem = tuple[str, str, str]   # key, message, fix


def _bus_problems(profile: Any, fmu: Any) -> list[Problem]:
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


def signal_bindings(profile: Any, fmu: Any, contract: Any,
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


def _signal_problems(profile: Any, fmu: Any) -> list[Problem]:
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


def fmu_problems(profile: Any, path: Path) -> list[Problem]:
    """Everything wrong with the profile's FMU, every problem at once.

    fmpy's validation, its interface, terminals, bindings and parameters: ``(key, message,
    fix)`` each.
    """
    from hil.fmi.fmufile import open_fmu, validate
    from hil.fmi.parameters import parameter_problems

    section = profile.fmu
    if section is None:
        return [("fmu", "a DUT of kind fmu needs an [fmu] section", "")]
    target = path
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


def check_fmu(profile: Any, path: Path) -> None:
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
