"""Rig table: name → class, from the ``agrihil.rigs`` entry point group.

The core names no rig: the built-in ones (the fertilizer and the sowing-depth rig) register
themselves in this project's ``pyproject.toml`` exactly as a third-party package adds a rig,
with an entry point ``NAME = "package.module:RigClass"`` in the group ``agrihil.rigs``; the
rig class brings its physics, devices, scenarios and bus contract (:mod:`hil.contract`).
"""

from __future__ import annotations

from functools import cache
from importlib.metadata import EntryPoint, entry_points

from hil.errors import ConfigError
from hil.rig.base import Rig

ENTRY_POINT_GROUP = "agrihil.rigs"


@cache
def _entry_points() -> dict[str, EntryPoint]:
    """The group's entry points by name (scanning installed metadata costs ~10 ms: once)."""
    return {ep.name.replace("-", "_"): ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_rigs() -> list[str]:
    """The names of every rig registered under the ``agrihil.rigs`` entry point group.

    Returns
    -------
    list of str
        Sorted rig names.
    """
    return sorted(_entry_points())


def load_rig(name: str) -> type[Rig]:
    """The rig class called ``name`` (``sowing-depth`` and ``sowing_depth`` are one rig).

    Parameters
    ----------
    name : str
        A rig registered under the ``agrihil.rigs`` entry point group.

    Returns
    -------
    type of Rig
        The rig class (imported on first use).

    Raises
    ------
    ConfigError
        No rig has that name (the message lists the available ones; with none at all, it says
        the package is not installed, since its own rigs register through its metadata).
    """
    key = name.replace("-", "_")
    eps = _entry_points()
    if key not in eps:
        if not eps:
            raise ConfigError(f"unknown rig {name!r}: no rig is registered (agrihil is not "
                              "installed: run scripts/setup.sh, or pip install -e .)",
                              key="rig")
        raise ConfigError(f"unknown rig {name!r}; available: {', '.join(available_rigs())}",
                          key="rig")
    return eps[key].load()  # type: ignore[no-any-return]
