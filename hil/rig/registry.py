"""Rig table: name → class, from the ``agrihil.rigs`` entry point group.

The core names no rig: the built-in ones (the fertilizer and the sowing-depth rig) register
themselves in this project's ``pyproject.toml`` exactly as a third-party package adds a rig,
with an entry point ``NAME = "package.module:RigClass"`` in the group ``agrihil.rigs``; the
rig class brings its physics, devices, scenarios and bus contract (:mod:`hil.contract`).

A rig of your own is a rig file (:mod:`hil.ownrig`): ``load_rig("path/to/motor.rig.toml")``
gives its class, and :func:`register_rig_file` makes it known by its name too (``hil run``,
``qualify``, ``campaign`` and ``gate`` do so for ``--rig FILE``), in this process and, through
the environment variable ``AGRIHIL_RIG_FILES`` (paths separated by ``os.pathsep``), in the
processes it starts (a campaign's workers).
"""

from __future__ import annotations

import os
from functools import cache
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path

from hil.errors import ConfigError
from hil.rig.base import Rig

ENTRY_POINT_GROUP = "agrihil.rigs"
#: rig files known in this process and the ones it starts
RIG_FILES_ENV = "AGRIHIL_RIG_FILES"


@cache
def _entry_points() -> dict[str, EntryPoint]:
    """The group's entry points by name (scanning installed metadata costs ~10 ms: once)."""
    return {ep.name.replace("-", "_"): ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def is_rig_file(name: str) -> bool:
    """Whether ``name`` is a rig file's path rather than a registered rig's name."""
    return name.endswith(".toml")


def _file_rigs() -> dict[str, Path]:
    """Rig name → rig file, for the files registered here or by a parent process."""
    from hil.ownrig.rig import rig_class

    out: dict[str, Path] = {}
    for text in os.environ.get(RIG_FILES_ENV, "").split(os.pathsep):
        if text:
            cls = rig_class(text)
            out[cls.name] = cls.rig_file
    return out


def register_rig_file(path: str | Path) -> type[Rig]:
    """Load a rig file and make its rig known by its name (here and in child processes).

    Returns
    -------
    type of Rig
        The rig's class (:func:`hil.ownrig.rig.rig_class`).

    Raises
    ------
    ConfigError
        The file is refused, or its name is a registered rig's (naming the key).
    """
    from hil.ownrig.rig import rig_class

    cls = rig_class(path)
    if cls.name in _entry_points():
        raise ConfigError(f"rig name {cls.name!r} is a built-in rig's: choose another",
                          path=str(path), key="name")
    known = _file_rigs()
    if known.get(cls.name, cls.rig_file) != cls.rig_file:
        raise ConfigError(f"rig name {cls.name!r} is also the rig file "
                          f"{known[cls.name]}'s", path=str(path), key="name")
    if cls.name not in known:
        paths = [p for p in os.environ.get(RIG_FILES_ENV, "").split(os.pathsep) if p]
        os.environ[RIG_FILES_ENV] = os.pathsep.join([*paths, str(cls.rig_file)])
    return cls


def rig_file_of(name: str) -> Path | None:
    """The rig file of a rig of your own (by its name or its path), None for other rigs."""
    if is_rig_file(name):
        return Path(name).resolve()
    return _file_rigs().get(name.replace("-", "_"))


def available_rigs() -> list[str]:
    """The names of every rig registered under the ``agrihil.rigs`` entry point group.

    Returns
    -------
    list of str
        Sorted rig names.
    """
    return sorted({*_entry_points(), *_file_rigs()})


def load_rig(name: str) -> type[Rig]:
    """The rig class called ``name`` (``sowing-depth`` and ``sowing_depth`` are one rig).

    Parameters
    ----------
    name : str
        A rig registered under the ``agrihil.rigs`` entry point group, a registered rig
        file's rig name, or a rig file's path (``*.toml``).

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
    if is_rig_file(name):
        from hil.ownrig.rig import rig_class

        return rig_class(name)
    key = name.replace("-", "_")
    eps = _entry_points()
    files = _file_rigs()
    if key in files and key not in eps:
        from hil.ownrig.rig import rig_class

        return rig_class(files[key])
    if key not in eps:
        if not eps:
            raise ConfigError(f"unknown rig {name!r}: no rig is registered (agrihil is not "
                              "installed: run scripts/setup.sh, or pip install -e .)",
                              key="rig")
        raise ConfigError(f"unknown rig {name!r}; available: {', '.join(available_rigs())}",
                          key="rig")
    return eps[key].load()  # type: ignore[no-any-return]
