"""Which implementation runs the rigs' hot loops: the compiled twins or the Python models.

The fertilizer rig's per-step models (the drive, meter and transport of
:mod:`~plant_emulators.fertilizer.physics`, ...) and the sowing-depth drive's steady
profile-velocity loop (:meth:`~plant_emulators.sowing_depth.cia402.Cia402Drive.run_pv_native`)
exist twice: the Python model, which is the readable reference, and a C twin compiled with the
package (``pip install -e .`` builds it, as
``scripts/setup.sh`` does). The twin does the same floating-point operations in the same order,
so both give the same floats bit for bit; the tests run both and compare. The twin is what
makes a lockstep run several times faster.

``AGRIHIL_PHYSICS`` selects the engine for a whole process: ``native`` (the default) or
``python``. There is no silent fallback: when the twin is not built, asking for it raises an
error that says how to build it or how to choose the Python models instead.

Example
-------
>>> physics_engine({"AGRIHIL_PHYSICS": "python"})
'python'
>>> physics_engine({})
'native'
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Mapping
from types import ModuleType
from typing import Literal

from hil.errors import ConfigError

__all__ = ["ENGINES", "ENV_VAR", "Engine", "load_native", "physics_engine", "resolve_engine"]

ENV_VAR = "AGRIHIL_PHYSICS"
Engine = Literal["native", "python"]
ENGINES: tuple[Engine, ...] = ("native", "python")


def _as_engine(value: str) -> Engine | None:
    """``value`` as an :data:`Engine`, or None when it names none."""
    if value == "native":
        return "native"
    if value == "python":
        return "python"
    return None


def physics_engine(environ: Mapping[str, str] | None = None) -> Engine:
    """The engine ``AGRIHIL_PHYSICS`` selects (``native`` when it is unset).

    Raises
    ------
    ConfigError
        When the variable holds anything else.
    """
    env = os.environ if environ is None else environ
    value = env.get(ENV_VAR, "native").strip().lower()
    checked = _as_engine(value)
    if checked is not None:
        return checked
    raise ConfigError(f"{ENV_VAR}={value!r}: expected one of {', '.join(ENGINES)}",
                      key=ENV_VAR)


def resolve_engine(engine: str | None) -> Engine:
    """``engine`` checked, or the process's choice (:func:`physics_engine`) when None."""
    if engine is None:
        return physics_engine()
    checked = _as_engine(engine)
    if checked is not None:
        return checked
    raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")


def load_native(module: str) -> ModuleType:
    """Import the compiled twin ``module``.

    Raises
    ------
    ImportError
        When it is not built, naming the module, how to build it and how to run the Python
        models instead.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ImportError(
            f"the compiled physics {module} is not built here ({exc}). Build it with "
            f"scripts/setup.sh (pip install -e .), which needs a C compiler, or run the "
            f"Python models with {ENV_VAR}=python") from exc
