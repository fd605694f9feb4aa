"""Rig table: name → class, extendable through the ``agrihil.rigs`` entry point group."""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points

from hil.errors import ConfigError
from hil.rig.base import Rig

RIGS: dict[str, str] = {
    "fertilizer": "plant_emulators.fertilizer.rig:FertilizerRig",
    "sowing_depth": "plant_emulators.sowing_depth.rig:SowingDepthRig",
}
ENTRY_POINT_GROUP = "agrihil.rigs"


def available_rigs() -> list[str]:
    """The names of every rig known: the built-in ones and those of the entry point group.

    Returns
    -------
    list of str
        Sorted rig names.
    """
    names = set(RIGS) | {ep.name for ep in entry_points(group=ENTRY_POINT_GROUP)}
    return sorted(names)


def load_rig(name: str) -> type[Rig]:
    """The rig class called ``name`` (``sowing-depth`` and ``sowing_depth`` are one rig).

    Parameters
    ----------
    name : str
        A built-in rig or one registered under the ``agrihil.rigs`` entry point group.

    Returns
    -------
    type of Rig
        The rig class (imported on first use).

    Raises
    ------
    ConfigError
        No rig has that name (the message lists the available ones).
    """
    name = name.replace("-", "_")
    target = RIGS.get(name)
    if target is None:
        eps = {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}
        if name not in eps:
            raise ConfigError(f"unknown rig {name!r}; available: {', '.join(available_rigs())}",
                              key="rig")
        return eps[name].load()  # type: ignore[no-any-return]
    module_name, _, attr = target.partition(":")
    return getattr(importlib.import_module(module_name), attr)  # type: ignore[no-any-return]
