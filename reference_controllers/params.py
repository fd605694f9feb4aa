"""Parameters from ``key=value`` pairs: a DUT profile's ``[parameters]`` or ``--param`` flags.

Every core keeps its parameters in a frozen dataclass; :func:`override` returns a copy with
some fields replaced from a mapping, converting strings to the field's type. A key the
dataclass does not have is an error that names it (a typo in a profile must not be ignored).

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class P:
...     gain: float = 1.0
...     mode: str = "a"
>>> override(P(), {"gain": "2.5"})
P(gain=2.5, mode='a')
>>> override(P(), {"gian": 2})
Traceback (most recent call last):
...
reference_controllers.params.ParamError: unknown parameter 'gian' (known: gain, mode)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, TypeVar

T = TypeVar("T")

ParamValue = str | float | int | bool


class ParamError(ValueError):
    """An unknown parameter name or a value that does not fit its parameter."""


def field_names(instance: Any) -> list[str]:
    """The parameter names of a parameter dataclass (or class)."""
    return [f.name for f in dataclasses.fields(instance)]


def _convert(name: str, current: Any, value: ParamValue) -> Any:
    if isinstance(current, str):
        return str(value)
    if isinstance(current, bool):
        if isinstance(value, str):
            if value.lower() in ("1", "true", "yes", "on"):
                return True
            if value.lower() in ("0", "false", "no", "off"):
                return False
            raise ParamError(f"parameter {name!r}: {value!r} is not a boolean")
        return bool(value)
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParamError(f"parameter {name!r}: {value!r} is not a number") from None
    if not math.isfinite(number):
        raise ParamError(f"parameter {name!r}: {value!r} is not finite")
    return number


def override(base: T, values: Mapping[str, ParamValue]) -> T:
    """``base`` with the fields named in ``values`` replaced (strings converted).

    Raises
    ------
    ParamError
        A key that is not a field of ``base`` (the message names it and lists the known
        ones), a value that does not convert, or a combination the dataclass rejects.
    """
    known = field_names(base)
    changes: dict[str, Any] = {}
    for key, value in values.items():
        if key not in known:
            raise ParamError(f"unknown parameter {key!r} (known: {', '.join(known)})")
        changes[key] = _convert(key, getattr(base, key), value)
    try:
        return dataclasses.replace(base, **changes)  # type: ignore[type-var]
    except ValueError as exc:
        raise ParamError(str(exc)) from exc


def split(values: Mapping[str, ParamValue], names: list[str]) -> tuple[
        dict[str, ParamValue], dict[str, ParamValue]]:
    """``values`` split into (the keys in ``names``, the rest)."""
    mine = {k: v for k, v in values.items() if k in names}
    rest = {k: v for k, v in values.items() if k not in names}
    return mine, rest


def as_text(instance: Any) -> str:
    """``key=value`` pairs of a parameter dataclass, floats in shortest round-trip form."""
    parts = []
    for name in field_names(instance):
        value = getattr(instance, name)
        parts.append(f"{name}={value!r}" if isinstance(value, float) else f"{name}={value}")
    return " ".join(parts)
