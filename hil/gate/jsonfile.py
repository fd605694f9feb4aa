"""Reading and writing the gate's JSON files, with errors that name the file and the key."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hil.errors import ConfigError


def read_json(path: str | Path, what: str) -> Any:
    """Parse ``path``; a missing, unreadable or malformed file is a :class:`ConfigError`."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as exc:
        raise ConfigError(f"{what} not found", path=str(path)) from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read {what}: {exc}", path=str(path)) from exc
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno})",
                          path=str(path)) from exc


def write_json(path: str | Path, data: Any) -> None:
    """Write ``data`` as indented JSON, atomically (a reader never sees half a file)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        tmp.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise ConfigError(f"cannot write: {exc}", path=str(path)) from exc


class Fields:
    """Typed access to one JSON object; every error names the file and the dotted key."""

    def __init__(self, data: Any, *, path: str, prefix: str = "") -> None:
        self.path = path
        self.prefix = prefix
        if not isinstance(data, Mapping):
            raise ConfigError(f"expected an object, got {_kind(data)}", path=path,
                              key=prefix or None)
        self.data: Mapping[str, Any] = data

    def key(self, name: str) -> str:
        return f"{self.prefix}.{name}" if self.prefix else name

    def error(self, name: str, message: str) -> ConfigError:
        return ConfigError(message, path=self.path, key=self.key(name))

    def _get(self, name: str, required: bool) -> Any:
        if name not in self.data:
            if required:
                raise self.error(name, "missing required key")
            return None
        return self.data[name]

    def string(self, name: str, *, required: bool = True, default: str = "") -> str:
        value = self._get(name, required)
        if value is None and not required:
            return default
        if not isinstance(value, str):
            raise self.error(name, f"expected a string, got {_kind(value)}")
        return value

    def number(self, name: str, *, required: bool = True,
               nullable: bool = True) -> float | None:
        """A finite number, or ``None`` for ``null`` and NaN ("no value") when ``nullable``."""
        if name not in self.data:
            if required:
                raise self.error(name, "missing required key")
            return None
        value = self.data[name]
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
            raise self.error(name, f"expected a number, got {_kind(value)}")
        if value is None or math.isnan(value):
            if not nullable:
                raise self.error(name, f"expected a number, got {_kind(value)}")
            return None
        if not math.isfinite(value):
            raise self.error(name, f"expected a finite number, got {value}")
        return float(value)

    def boolean(self, name: str, *, required: bool = True, default: bool = False) -> bool:
        value = self._get(name, required)
        if value is None and not required:
            return default
        if not isinstance(value, bool):
            raise self.error(name, f"expected true/false, got {_kind(value)}")
        return value

    def mapping(self, name: str, *, required: bool = True) -> dict[str, Any]:
        value = self._get(name, required)
        if value is None and not required:
            return {}
        if not isinstance(value, Mapping):
            raise self.error(name, f"expected an object, got {_kind(value)}")
        return dict(value)

    def array(self, name: str, *, required: bool = True) -> list[Any]:
        value = self._get(name, required)
        if value is None and not required:
            return []
        if not isinstance(value, list):
            raise self.error(name, f"expected an array, got {_kind(value)}")
        return value

    def child(self, name: str, *, required: bool = True) -> Fields:
        value = self._get(name, required)
        return Fields({} if value is None else value, path=self.path, prefix=self.key(name))


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, str):
        return f"the string {value!r}"[:60]
    if isinstance(value, int | float):
        return f"the number {value!r}"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, Mapping):
        return "an object"
    return type(value).__name__
