"""TOML files into frozen dataclasses, with errors that name the file and the key.

Every configuration in agrihil (rig configs, DUT profiles, scenarios) is pure data: a frozen
dataclass whose fields map one-to-one onto TOML keys. :func:`from_mapping` builds one from a
mapping and rejects unknown keys, missing keys and wrong types; :func:`load_toml` reads a file
and does the same, naming the file in every error.

Supported field types: ``bool``, ``int``, ``float`` (ints accepted), ``str``, nested frozen
dataclasses, ``tuple[T, ...]`` of those, ``dict[str, T]``, ``Literal[...]`` and ``X | None``.

Example
-------
>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Motor:
...     ke_v_per_krpm: float
...     poles: int = 2
>>> from_mapping(Motor, {"ke_v_per_krpm": 7.1})
Motor(ke_v_per_krpm=7.1, poles=2)
>>> from_mapping(Motor, {"ke_v_per_krpm": 7.1, "pole": 3})
Traceback (most recent call last):
...
hil.errors.ConfigError: [pole] unknown key (expected one of: ke_v_per_krpm, poles)
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, TypeVar, get_args, get_origin, get_type_hints

from hil.errors import ConfigError

T = TypeVar("T")


def load_toml(path: str | Path, cls: type[T], *, section: str | None = None,
              overrides: Mapping[str, Any] | None = None, source: str | None = None) -> T:
    """Read ``path`` (optionally only its ``[section]``) into the frozen dataclass ``cls``.

    ``overrides`` (nested tables, e.g. a DUT profile's ``[rig]``) replace the file's values
    key by key before validation; errors then name ``source`` (where the overrides come from)
    as well as the file.
    """
    path = Path(path)
    data = read_toml(path)
    if section is not None:
        if section not in data:
            raise ConfigError("missing section", path=str(path), key=section)
        data = data[section]
    label = str(path)
    if overrides:
        data = merge_tables(data, overrides)
        label = f"{source or 'overrides'} (over {path.name})"
    return from_mapping(cls, data, path=label, prefix=section or "")


def read_toml(path: Path, what: str = "file") -> dict[str, Any]:
    """Parse the TOML file ``path``: missing, unreadable, not UTF-8 or not TOML is a
    :class:`ConfigError` naming the file (and where in it)."""
    try:
        raw = path.read_bytes()
    except FileNotFoundError as exc:
        raise ConfigError(f"{what} not found", path=str(path)) from exc
    except OSError as exc:
        raise ConfigError(f"cannot read {what}: {exc.strerror or exc}", path=str(path)) from exc
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not UTF-8 text (TOML files are UTF-8): byte 0x{raw[exc.start]:02x} "
                          f"at offset {exc.start}", path=str(path)) from exc
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {one_line(str(exc))}", path=str(path)) from exc


def key_text(key: object) -> str:
    """A key as it can appear in a one-line error: itself when printable, else its repr."""
    text = str(key)
    return text if text and text.isprintable() and text.strip() == text else repr(text)


def one_line(text: str, limit: int = 300) -> str:
    """``text`` on one line of printable characters, at most ``limit`` long."""
    flat = " ".join(text.split())
    flat = "".join(c if c.isprintable() else "?" for c in flat)
    return flat if len(flat) <= limit else flat[:limit - 1] + "…"


def merge_tables(base: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``overrides`` applied key by key (tables merge, other values replace)."""
    out = dict(base)
    for key, value in overrides.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge_tables(out[key], value)
        else:
            out[key] = value
    return out


def from_mapping(cls: type[T], data: Mapping[str, Any], *, path: str | None = None,
                 prefix: str = "") -> T:
    """Build the dataclass ``cls`` from ``data``; errors name ``path`` and the dotted key."""
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"{cls!r} is not a dataclass")
    if not isinstance(data, Mapping):
        raise ConfigError(f"expected a table, got {type(data).__name__}", path=path,
                          key=prefix or None)
    hints = get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = [k for k in data if k not in fields]
    if unknown:
        raise ConfigError(
            f"unknown key (expected one of: {', '.join(sorted(fields))})",
            path=path, key=_join(prefix, key_text(unknown[0])))
    kwargs: dict[str, Any] = {}
    for name, field in fields.items():
        key = _join(prefix, name)
        if name not in data:
            if (field.default is dataclasses.MISSING
                    and field.default_factory is dataclasses.MISSING):
                raise ConfigError("missing required key", path=path, key=key)
            continue
        kwargs[name] = _convert(hints[name], data[name], path=path, key=key)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ConfigError):
            if exc.path or not path:
                raise
            # a check in __post_init__ names the key but cannot know the file: add it
            message = str(exc)
            if exc.key and message.startswith(f"[{exc.key}] "):
                message = message[len(exc.key) + 3:]
            key = _join(prefix, exc.key) if exc.key else (prefix or None)
            raise ConfigError(message, path=path, key=key) from exc
        raise ConfigError(one_line(str(exc)), path=path, key=prefix or None) from exc


def _join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def _convert(tp: Any, value: Any, *, path: str | None, key: str) -> Any:
    origin = get_origin(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        options = get_args(tp)
        if value is None and type(None) in options:
            return None
        non_none = [o for o in options if o is not type(None)]
        if len(non_none) == 1:
            return _convert(non_none[0], value, path=path, key=key)
        errors = []
        for option in options:
            if option is type(None):
                continue
            try:
                return _convert(option, value, path=path, key=key)
            except ConfigError as exc:
                errors.append(str(exc))
        raise ConfigError(f"{_short(value)} matches none of {tp}", path=path, key=key)
    if origin is Literal:
        allowed = get_args(tp)
        if value not in allowed:
            raise ConfigError(f"{_short(value)} is not one of {list(allowed)}", path=path,
                              key=key)
        return value
    if origin is tuple:
        args = get_args(tp)
        if not isinstance(value, list | tuple):
            raise ConfigError(f"expected an array, got {type(value).__name__}", path=path,
                              key=key)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, path=path, key=f"{key}[{i}]")
                         for i, v in enumerate(value))
        if len(args) != len(value):
            raise ConfigError(f"expected {len(args)} items, got {len(value)}", path=path,
                              key=key)
        return tuple(_convert(a, v, path=path, key=f"{key}[{i}]")
                     for i, (a, v) in enumerate(zip(args, value, strict=True)))
    if origin is dict:
        _, vtype = get_args(tp)
        if not isinstance(value, Mapping):
            raise ConfigError(f"expected a table, got {type(value).__name__}", path=path,
                              key=key)
        return {str(k): _convert(vtype, v, path=path, key=f"{key}.{key_text(k)}")
                for k, v in value.items()}
    if dataclasses.is_dataclass(tp):
        return from_mapping(tp, value, path=path, prefix=key)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"expected true/false, got {_short(value)}", path=path, key=key)
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"expected an integer, got {_short(value)}", path=path, key=key)
        if not -(2**63) <= value < 2**63:
            raise ConfigError(f"integer out of range (64-bit): {_short(value)}", path=path,
                              key=key)
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"expected a number, got {_short(value)}", path=path, key=key)
        try:
            number = float(value)
        except OverflowError as exc:
            raise ConfigError(f"number out of range: {_short(value)}", path=path,
                              key=key) from exc
        if not math.isfinite(number):
            raise ConfigError(f"expected a finite number, got {value!r}", path=path, key=key)
        return number
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"expected a string, got {_short(value)}", path=path, key=key)
        return value
    raise TypeError(f"unsupported field type {tp!r} at {key}")


def _short(value: Any) -> str:
    return one_line(repr(value), 60)


def check_positive(obj: object, *names: str) -> None:
    """Raise ``ValueError`` naming the first field of ``obj`` among ``names`` that is not > 0.

    For ``__post_init__`` of config dataclasses; :func:`from_mapping` turns the error into a
    :class:`ConfigError` naming the file and table."""
    for name in names:
        value = getattr(obj, name)
        if not value > 0:
            raise ValueError(f"{name} must be > 0, got {value!r}")


def check_non_negative(obj: object, *names: str) -> None:
    """As :func:`check_positive`, for fields that must be >= 0."""
    for name in names:
        value = getattr(obj, name)
        if not value >= 0:
            raise ValueError(f"{name} must be >= 0, got {value!r}")


def check_fraction(obj: object, *names: str) -> None:
    """As :func:`check_positive`, for fields that must lie in [0, 1)."""
    for name in names:
        value = getattr(obj, name)
        if not 0 <= value < 1:
            raise ValueError(f"{name} must be in [0, 1), got {value!r}")
