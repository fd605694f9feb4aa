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
    """Add a transport at run time (tests, plugins that cannot use entry points).

    Parameters
    ----------
    name : str
        The name specs start with (case-insensitive); it takes precedence over a built-in or
        entry point transport of that name.
    opener : callable
        ``opener(spec: BusSpec) -> can.BusABC``.
    """
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
    """Open the bus a spec names.

    Parameters
    ----------
    spec : str or BusSpec
        ``TRANSPORT[:CHANNEL][,key=value...]``: a built-in transport (``virtual``,
        ``socketcan``, ``socketcand``), one registered or declared as an entry point, or any
        python-can interface.

    Returns
    -------
    can.BusABC
        The open bus; the caller shuts it down.

    Raises
    ------
    BusSpecError
        The spec cannot be parsed or names an unknown transport (the message lists the
        available ones).
    BusError
        The transport could not open the bus.
    """
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
