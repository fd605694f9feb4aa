"""Where a rig's qualification suites live: the ``agrihil.suites`` entry points.

A package that ships a rig ships its suites and declares them, rig name to the Python package
holding the suite files::

    [project.entry-points."agrihil.suites"]
    fertilizer = "test_suites.fertilizer"

``hil qualify`` hands pytest that package's directory only (the other rigs' suites are never
collected) with the ``pytest.ini`` found in it or the nearest package above it. agrihil's own
rigs are declared in its ``pyproject.toml``.
"""

from __future__ import annotations

import importlib.util
from importlib import metadata
from pathlib import Path

from hil.errors import ConfigError

GROUP = "agrihil.suites"


def _norm(rig: str) -> str:
    return rig.replace("-", "_")


def registered_suites() -> dict[str, str]:
    """Rig name (``-`` as ``_``) to the package of its suites, from the entry points."""
    return {_norm(ep.name): ep.value.split(":", 1)[0]
            for ep in metadata.entry_points(group=GROUP)}


def suite_location(rig: str) -> tuple[Path, Path]:
    """The directory of ``rig``'s suites and the ``pytest.ini`` to run them with.

    Parameters
    ----------
    rig : str
        The rig's name (``sowing-depth`` and ``sowing_depth`` are the same rig).

    Returns
    -------
    tuple of Path
        The suites' directory and its ``pytest.ini``.

    Raises
    ------
    ConfigError
        No suites are registered for the rig, or the registered package cannot be found.
    """
    packages = registered_suites()
    package = packages.get(_norm(rig))
    if package is None:
        from hil.rig.registry import rig_file_of

        if rig_file_of(rig) is not None:      # a rig of your own: the standard own-rig suites
            package = "test_suites.own_rig"
    if package is None:
        known = ", ".join(sorted(packages)) or "none (is agrihil installed? pip install -e .)"
        raise ConfigError(f"no qualification suites are registered for the rig {rig!r} "
                          f"(entry point group {GROUP!r}; registered: {known})", key="dut.rig")
    try:
        spec = importlib.util.find_spec(package)
    except (ImportError, ValueError) as exc:
        raise ConfigError(f"the suites of rig {rig!r} ({package}) cannot be found: {exc}",
                          key="dut.rig") from exc
    if spec is None or not spec.submodule_search_locations:
        raise ConfigError(f"the suites of rig {rig!r} ({package}) are not a package",
                          key="dut.rig")
    directory = Path(next(iter(spec.submodule_search_locations))).resolve()
    for candidate in (directory, *directory.parents):
        ini = candidate / "pytest.ini"
        if ini.is_file():
            return directory, ini
        if not (candidate / "__init__.py").exists():
            break
    raise ConfigError(f"the suites of rig {rig!r} ({directory}) have no pytest.ini in their "
                      f"package or the packages above it", key="dut.rig")
