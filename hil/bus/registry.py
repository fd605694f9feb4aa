"""Transport table: spec name → opener, extendable through entry points.

The core never imports a particular transport: names map to ``"module:function"`` strings that
are imported only when asked for (as python-can's ``BACKENDS``). A package adds a transport by
declaring an entry point in the group ``agrihil.transports`` whose object is a callable
``opener(spec: BusSpec) -> can.BusABC``. Any other python-can interface installed on the machine
works as ``<interface>:<channel>[,key=value…]``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from importlib.metadata import entry_points

import can

from hil.bus.spec import BusSpec, parse_spec
from hil.errors import BusError, BusSpecError

Opener = Callable[[BusSpec], can.BusABC]

#: Built-in transports, imported lazily.
TRANSPORTS: dict[str, str] = {
    "virtual": "hil.bus.transports:open_virtual",
    "socketcan": "hil.bus.transports:open_socketcan",
    "socketcand": "hil.bus.transports:open_socketcand",
}
ENTRY_POINT_GROUP = "agrihil.transports"
_registered: dict[str, Opener] = {}


def register_transport(name: str, opener: Opener) -> None:
    """Add a transport at run time (tests, plugins that cannot use entry points)."""
    _registered[name.lower()] = opener


def _entry_point_transports() -> dict[str, object]:
    return {ep.name.lower(): ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_transports() -> list[str]:
    """Every transport name a spec may start with."""
    names = set(TRANSPORTS) | set(_registered) | set(_entry_point_transports())
    names |= set(can.interfaces.VALID_INTERFACES)
    return sorted(names)


def _resolve(name: str) -> Opener | None:
    if name in _registered:
        return _registered[name]
    if name in TRANSPORTS:
        module_name, _, attr = TRANSPORTS[name].partition(":")
        return getattr(importlib.import_module(module_name), attr)  # type: ignore[no-any-return]
    eps = _entry_point_transports()
    if name in eps:
        return eps[name].load()  # type: ignore[attr-defined,no-any-return]
    if name in can.interfaces.VALID_INTERFACES:
        from hil.bus.transports import open_python_can
        return open_python_can
    return None


def open_bus(spec: str | BusSpec) -> can.BusABC:
    """Open the bus a spec names. Unknown specs fail with the list of what is available."""
    parsed = parse_spec(spec) if isinstance(spec, str) else spec
    opener = _resolve(parsed.transport)
    if opener is None:
        raise BusSpecError(f"unknown bus transport {parsed.transport!r} in spec '{spec}'; "
                           f"available: {', '.join(available_transports())}")
    try:
        return opener(parsed)
    except (BusError, BusSpecError):
        raise
    except (can.CanError, OSError, ValueError, ImportError, TypeError) as exc:
        raise BusError(f"cannot open bus '{spec}': {exc}") from exc
