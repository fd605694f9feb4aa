"""A measurement's identity: its name plus its sorted conditions, as one string.

>>> measurement_key("depth.field.pass_rate", {})
'depth.field.pass_rate'
>>> measurement_key("flow.step.overshoot", {"target_gps": 23.0, "sensor": "block"})
'flow.step.overshoot[sensor=block,target_gps=23]'
>>> format_conditions({"speed_kmh": 6, "dry": True})
'dry=true, speed_kmh=6'

Numbers are written so that ``23`` and ``23.0`` are the same condition (JSON does not keep the
difference reliably); booleans and ``null`` as JSON spells them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any


def condition_value(value: Any) -> str:
    """One condition value as text (the same text for equal numbers of either type)."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isfinite(value) and value == int(value):
            return str(int(value))
        return repr(value)
    if isinstance(value, str):
        return value
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


def _pairs(conditions: Mapping[str, Any]) -> list[str]:
    return [f"{k}={condition_value(conditions[k])}" for k in sorted(conditions)]


def measurement_key(name: str, conditions: Mapping[str, Any]) -> str:
    """``name`` alone, or ``name[k1=v1,k2=v2]`` with the conditions sorted by key."""
    if not conditions:
        return name
    return f"{name}[{','.join(_pairs(conditions))}]"


def format_conditions(conditions: Mapping[str, Any]) -> str:
    """The conditions for people: ``k1=v1, k2=v2`` sorted by key (empty when none)."""
    return ", ".join(_pairs(conditions))
