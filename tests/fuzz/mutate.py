"""Mutations of the files users hand agrihil, as Hypothesis strategies.

A shipped file is parsed, one mutation is drawn (delete, retype, duplicate or rename a key;
a huge, negative, NaN or infinite number; truncation; a wrong encoding; stray bytes) and the
result is written back as bytes. :func:`mutated` is the strategy; it yields
``(description, bytes)`` so a failure says what was done.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

ODD_VALUES: list[Any] = [
    None, True, False, 0, -1, -1000, 10**30, -(10**30), 1e308, -1e308, math.nan, math.inf,
    -math.inf, 0.0, -0.0, 1e-320, "", "x", "fast", "\u00e9\u4e2d", [], [1, "a"], {},
    {"a": 1}, "1e9", "-1", "NaN",
]


# --- TOML writing (no writer in the standard library) --------------------------------------
def _toml_key(key: str) -> str:
    return json.dumps(key, ensure_ascii=True)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=True)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value if v is not None) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}"
                                for k, v in value.items() if v is not None) + " }"
    return json.dumps(str(value))


def to_toml(data: dict[str, Any]) -> str:
    """Every key at the top level, nested tables inline (TOML has no null: dropped)."""
    return "".join(f"{_toml_key(k)} = {_toml_value(v)}\n" for k, v in data.items()
                   if v is not None)


# --- paths into nested data ----------------------------------------------------------------
def paths(data: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every key path (dict keys and list indices) into ``data``."""
    found: list[tuple[Any, ...]] = []
    if isinstance(data, dict):
        for key, value in data.items():
            found.append((*prefix, key))
            found.extend(paths(value, (*prefix, key)))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            found.append((*prefix, i))
            found.extend(paths(value, (*prefix, i)))
    return found


def _parent(data: Any, path: tuple[Any, ...]) -> Any:
    for part in path[:-1]:
        data = data[part]
    return data


def _copy(data: Any) -> Any:
    return json.loads(json.dumps(data, allow_nan=True, default=str))


def apply(data: Any, action: str, path: tuple[Any, ...], value: Any = None) -> Any:
    """``data`` with one structural mutation at ``path``."""
    data = _copy(data)
    parent = _parent(data, path)
    last = path[-1]
    if action == "delete":
        del parent[last]
    elif action == "retype":
        parent[last] = value
    elif action == "rename":
        if isinstance(parent, dict):
            parent[f"{last}_x" if value is None else str(value)] = parent.pop(last)
        else:
            parent[last] = value
    return data


# --- strategies ----------------------------------------------------------------------------
@st.composite
def structural(draw: st.DrawFn, data: Any, encode: Any) -> tuple[str, bytes]:
    """Delete, retype or rename one key of ``data``; ``encode(data) -> bytes``."""
    where = draw(st.sampled_from(paths(data)))
    action = draw(st.sampled_from(["delete", "retype", "rename"]))
    value: Any = None
    if action == "retype":
        value = draw(st.sampled_from(ODD_VALUES) | st.floats(allow_nan=True)
                     | st.integers(min_value=-(2**70), max_value=2**70)
                     | st.text(max_size=8))
    elif action == "rename":
        value = draw(st.none() | st.text(min_size=1, max_size=6))
    return f"{action} {'.'.join(map(str, where))} -> {value!r}", encode(
        apply(data, action, where, value))


@st.composite
def textual(draw: st.DrawFn, text: str) -> tuple[str, bytes]:
    """Damage to the file as text: truncate, duplicate a line, wrong encoding, bad bytes."""
    raw = text.encode("utf-8")
    kind = draw(st.sampled_from(["truncate", "duplicate-line", "utf-16", "latin-1", "bytes",
                                 "empty"]))
    if kind == "truncate":
        cut = draw(st.integers(min_value=0, max_value=max(0, len(raw) - 1)))
        return f"truncate at byte {cut}", raw[:cut]
    if kind == "duplicate-line":
        lines = text.splitlines(keepends=True)
        candidates = [i for i, line in enumerate(lines) if "=" in line or ":" in line]
        if not candidates:
            return "unchanged", raw
        i = draw(st.sampled_from(candidates))
        doubled = [*lines[:i + 1], lines[i], *lines[i + 1:]]
        return f"duplicate line {i + 1}", "".join(doubled).encode()
    if kind == "utf-16":
        return "UTF-16", text.encode("utf-16")
    if kind == "latin-1":
        return "Latin-1 with a non-ASCII comment", ("# caf\u00e9 " + "\n" + text).encode(
            "latin-1", errors="replace").replace(b"caf?", b"caf\xe9")
    if kind == "bytes":
        at = draw(st.integers(min_value=0, max_value=len(raw)))
        junk = draw(st.binary(min_size=1, max_size=4).filter(lambda b: b"\n" not in b))
        return f"insert {junk!r} at {at}", raw[:at] + junk + raw[at:]
    return "empty file", b""


def toml_mutations(path: Path) -> st.SearchStrategy[tuple[str, bytes]]:
    """Structural and textual mutations of the TOML file ``path``."""
    text = path.read_text(encoding="utf-8")
    data = tomllib.loads(text)
    return st.one_of(structural(data, lambda d: to_toml(d).encode("utf-8")), textual(text))


def json_mutations(path: Path) -> st.SearchStrategy[tuple[str, bytes]]:
    """Structural and textual mutations of the JSON file ``path``."""
    text = path.read_text(encoding="utf-8")
    data = json.loads(text)
    return st.one_of(
        structural(data, lambda d: json.dumps(d, allow_nan=True).encode("utf-8")),
        textual(text))
