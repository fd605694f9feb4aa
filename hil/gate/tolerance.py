"""Tolerance bands: how much worse than its baseline a measurement may get before it regresses.

A TOML file (``ci/tolerances.toml`` is the project's)::

    [default]                                 # every measurement not named below
    rel = 0.05                                # 5 % of the baseline value

    [measurements]
    "flow.step.response_time" = { abs = 0.10 }            # in the measurement's unit (s)
    "flow.step.*"             = { abs = 0.5, rel = 0.1 }  # glob on the name

A band has ``abs`` (in the measurement's unit) and/or ``rel`` (a fraction of the baseline's
magnitude); with both, the wider one applies. Which band a measurement gets: its exact name, else
the matching glob with the most literal characters (the most specific), else the file's order;
else ``[default]``. Without ``[default]`` (or without a file) the built-in default applies:
``rel = 0.05``.

Names and globs must fit the measurement catalogue (:mod:`hil.limits`): a band for a name no suite
records is a typo, and a typo would silently leave a measurement with the default band.
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.config import from_mapping, key_text, one_line, read_toml
from hil.errors import ConfigError
from hil.limits import MEASUREMENTS

_GLOB_CHARS = "*?["


@dataclass(frozen=True)
class Band:
    """``abs`` in the measurement's unit, ``rel`` as a fraction of ``|baseline|``."""

    abs: float | None = None
    rel: float | None = None

    def __post_init__(self) -> None:
        if self.abs is None and self.rel is None:
            raise ValueError("a band needs abs and/or rel")
        for name in ("abs", "rel"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")

    def width(self, reference: float) -> float:
        """The band around a baseline value ``reference``, in the measurement's unit."""
        return max(self.abs or 0.0, (self.rel or 0.0) * abs(reference))

    def describe(self) -> str:
        parts = []
        if self.abs is not None:
            parts.append(f"abs {self.abs:g}")
        if self.rel is not None:
            parts.append(f"rel {self.rel:g}")
        return ", ".join(parts)


@dataclass(frozen=True)
class Tolerances:
    default: Band = field(default_factory=lambda: Band(rel=0.05))
    exact: dict[str, Band] = field(default_factory=dict)
    #: (glob, band) in file order
    patterns: tuple[tuple[str, Band], ...] = ()
    path: str = ""

    def band_for(self, name: str) -> tuple[Band, str]:
        """The band of measurement ``name`` and where it came from (for the summary)."""
        if name in self.exact:
            return self.exact[name], name
        matching = [(i, glob, band) for i, (glob, band) in enumerate(self.patterns)
                    if fnmatch.fnmatchcase(name, glob)]
        if matching:
            _, glob, band = max(matching, key=lambda item: (_literal_chars(item[1]), -item[0]))
            return band, glob
        return self.default, "default"

    def describe(self) -> str:
        return self.path or f"built-in default band ({self.default.describe()})"


DEFAULT_TOLERANCES = Tolerances()


def load_tolerances(path: str | Path) -> Tolerances:
    """Read a tolerance file; unknown keys, negative or empty bands and names that match no
    catalogued measurement are :class:`ConfigError` naming the file and the key."""
    data = read_toml(Path(path), "tolerance file")
    path = str(path)
    unknown = [k for k in data if k not in ("default", "measurements")]
    if unknown:
        raise ConfigError("unknown key (expected one of: default, measurements)", path=path,
                          key=key_text(unknown[0]))
    default = (_band(data["default"], path=path, key="default") if "default" in data
               else DEFAULT_TOLERANCES.default)
    table = data.get("measurements", {})
    if not isinstance(table, dict):
        raise ConfigError(f"expected a table, got {type(table).__name__}", path=path,
                          key="measurements")
    exact: dict[str, Band] = {}
    patterns: list[tuple[str, Band]] = []
    for name, value in table.items():
        shown = key_text(name)
        key = f'measurements."{name}"' if shown == name else f"measurements.{shown}"
        band = _band(value, path=path, key=key)
        if any(c in name for c in _GLOB_CHARS):
            if not any(fnmatch.fnmatchcase(known, name) for known in MEASUREMENTS):
                raise ConfigError("pattern matches no known measurement name (see "
                                  "hil/limits.py)", path=path, key=key)
            patterns.append((name, band))
        else:
            if name not in MEASUREMENTS:
                raise ConfigError("unknown measurement name (see hil/limits.py)", path=path,
                                  key=key)
            exact[name] = band
    return Tolerances(default=default, exact=exact, patterns=tuple(patterns), path=path)


def _band(value: Any, *, path: str, key: str) -> Band:
    if not isinstance(value, dict):
        raise ConfigError(f"expected a table like {{ abs = 0.1 }}, got "
                          f"{one_line(repr(value), 60)}", path=path, key=key)
    return from_mapping(Band, value, path=path, prefix=key)


def _literal_chars(glob: str) -> int:
    return sum(1 for c in glob if c not in _GLOB_CHARS)
