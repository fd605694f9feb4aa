"""Where a rig's bus contract comes from: the rig's own registration, never the core.

A rig is registered by name (the ``agrihil.rigs`` entry point group, :mod:`hil.rig.registry`);
its class says what its bus contract is with a class method::

    class MyRig(Rig):
        @classmethod
        def bus_contract(cls, overrides: Mapping[str, Any], source: str) -> Contract: ...

so the core reaches a rig's quantities, databases, nodes, default binding and dispersion file
through the rig's name alone, and adding a rig needs no edit here.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hil.contract.quantity import Contract
from hil.errors import ConfigError

__all__ = ["dispersion_file", "rig_contract"]


def rig_contract(rig: str, overrides: Mapping[str, Any] | None = None,
                 source: str = "") -> Contract:
    """The bus contract of ``rig`` with the ``overrides`` of its config applied.

    Parameters
    ----------
    rig : str
        A registered rig (``sowing-depth`` and ``sowing_depth`` are one rig).
    overrides : mapping, optional
        A profile's ``[rig]`` table.
    source : str, optional
        Where the overrides come from, named in errors.

    Returns
    -------
    Contract
        Its quantities, rows, binding in force, databases, nodes and periods.

    Raises
    ------
    ConfigError
        The rig is unknown, declares no bus contract, or its config refuses the overrides.
    """
    from hil.rig.registry import load_rig

    rig_cls = load_rig(rig)
    describe = getattr(rig_cls, "bus_contract", None)
    if describe is None:
        raise ConfigError(f"the {rig} rig declares no bus contract (a bus_contract class "
                          f"method on {rig_cls.__name__})", key="dut.rig")
    contract = describe(overrides or {}, source)
    if not isinstance(contract, Contract):
        raise ConfigError(f"{rig_cls.__name__}.bus_contract returned "
                          f"{type(contract).__name__}, not a Contract", key="dut.rig")
    return contract


def dispersion_file(rig: str) -> Path:
    """The dispersion file the rig ships for ``hil campaign``.

    Raises
    ------
    ConfigError
        The rig ships none.
    """
    path = rig_contract(rig).dispersion_file
    if path is None:
        raise ConfigError(f"the {rig} rig ships no dispersion file", key="dispersion")
    return path
