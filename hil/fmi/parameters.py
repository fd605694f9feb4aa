"""A DUT profile's ``[parameters]`` as the FMU's parameters, set before initialisation."""

from __future__ import annotations

from typing import Any

from hil.fmi.fmufile import FmuFile
from hil.fmi.instance import FmuCallError, FmuInstance

__all__ = ["apply_parameters", "environment_parameters", "parameter_problems"]

PARAMETER_CAUSALITIES = ("parameter", "structuralParameter")


def parameter_problems(fmu: FmuFile, parameters: dict[str, Any]) -> list[tuple[str, str]]:
    """``(key, problem)`` for each profile parameter the FMU cannot take."""
    problems: list[tuple[str, str]] = []
    names = sorted(v.name for v in fmu.variables.values()
                   if v.causality in PARAMETER_CAUSALITIES)
    for name, value in parameters.items():
        var = fmu.variable(name)
        key = f"parameters.{name}"
        if var is None or var.causality not in PARAMETER_CAUSALITIES:
            problems.append((key, f"the FMU has no parameter {name!r} (its parameters: "
                                  f"{', '.join(names) or 'none'})"))
        elif var.variability == "constant":
            problems.append((key, f"{name} is a constant of the FMU"))
        elif isinstance(value, str) != (var.type == "String"):
            problems.append((key, f"{name} is a {var.type} of the FMU, the profile gives "
                                  f"{value!r}"))
    return problems


def apply_parameters(inst: FmuInstance, fmu: FmuFile, parameters: dict[str, Any]) -> None:
    """Set each parameter on the instance (before initialisation).

    Raises
    ------
    FmuCallError
        A parameter the FMU does not have or refuses.
    """
    for key, problem in parameter_problems(fmu, parameters):
        raise FmuCallError(f"[{key}] {problem}")
    for name, value in parameters.items():
        var = fmu.variable(name)
        if isinstance(value, str):
            inst.call("setString", [var.valueReference], [value])
        else:
            inst.set(var, value)


def environment_parameters(fmu: FmuFile, env: dict[str, str]) -> dict[str, str]:
    """What the rig offers besides the bus (``AGRIHIL_GNSS_PORT``, say), for the FMU's string
    parameters of the same name in lower case (``agrihil_gnss_port``)."""
    out = {}
    for key, value in env.items():
        var = fmu.variable(key.lower())
        if var is not None and var.type == "String" and \
                var.causality in PARAMETER_CAUSALITIES:
            out[var.name] = value
    return out
