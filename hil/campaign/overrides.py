"""Rig config overrides as ``KEY=VALUE`` strings: dotted keys, TOML values.

A campaign sample's rig is the packaged config, the profile's ``[rig]`` and the dispersed
parameters, in that order. The dispersed ones travel as dotted ``KEY=VALUE`` strings (the
``--rig-override`` of ``hil qualify``), written with ``repr`` of the float so that the value a
reproduce command carries is the very float the sample ran with.

>>> format_override("fertilizer.density_offset_mean_frac", -0.0312)
'fertilizer.density_offset_mean_frac=-0.0312'
>>> nested({"meter.row_spread_sd_frac": 0.02})
{'meter': {'row_spread_sd_frac': 0.02}}
"""

from __future__ import annotations

import tomllib
from collections.abc import Iterable, Mapping
from typing import Any

from hil.config import merge_tables
from hil.errors import ConfigError


def format_override(key: str, value: Any) -> str:
    """``key=value`` with the value as a TOML literal (floats round-trip exactly)."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, float):
        text = repr(value)
    elif isinstance(value, str):
        text = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    else:
        text = str(value)
    return f"{key}={text}"


def nested(dotted: Mapping[str, Any]) -> dict[str, Any]:
    """``{"a.b": 1}`` as ``{"a": {"b": 1}}``."""
    out: dict[str, Any] = {}
    for key, value in dotted.items():
        *tables, leaf = key.split(".")
        node = out
        for table in tables:
            node = node.setdefault(table, {})
        node[leaf] = value
    return out


def parse_overrides(items: Iterable[str], *, rig: str,
                    base: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Parse ``KEY=VALUE`` strings into a nested override table, checked by ``rig``'s loader
    (on top of ``base``, a profile's ``[rig]``). Raises :class:`ConfigError` naming the
    item that is malformed or that the rig's config rejects."""
    dotted: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key or not all(part.isidentifier() for part in key.split(".")):
            raise ConfigError(f"expected KEY=VALUE with a dotted key, got {item!r}")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{item!r}: the value is not a TOML value ({exc})",
                              key=key) from exc
        dotted[key] = value
    table = nested(dotted)
    from hil.rig.registry import load_rig

    load_rig(rig).load_config(merge_tables(dict(base or {}), table),
                              source="--rig-override")
    return table
