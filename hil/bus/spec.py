"""Bus spec strings: ``TRANSPORT[:CHANNEL][,key=value…]``.

Examples: ``virtual``, ``virtual:rig1``, ``socketcan:vcan0``, ``socketcand:127.0.0.1:29536/can0``,
``pcan:PCAN_USBBUS1,bitrate=250000``, ``slcan:/dev/ttyACM0,bitrate=250000``.
Option values are read as booleans (``true``/``false``), integers (``250000``, ``0x80``),
floats, or else kept as strings.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from hil.errors import BusSpecError

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")


@dataclass(frozen=True)
class BusSpec:
    """A parsed bus spec: ``TRANSPORT[:CHANNEL][,key=value...]``; ``str()`` gives the spec back.

    Parameters
    ----------
    transport : str
        The transport name, lower case (``virtual``, ``socketcan``, ``socketcand``, ``pcan``...).
    channel : str, optional
        What follows the first ``:`` (an interface, ``host:port/channel``, a device path).
    options : dict, optional
        The ``key=value`` options, values read as booleans, integers, floats or strings.
    """

    transport: str
    channel: str | None = None
    options: dict[str, bool | int | float | str] = field(default_factory=dict)

    def __str__(self) -> str:
        text = self.transport + (f":{self.channel}" if self.channel else "")
        return text + "".join(f",{k}={v}" for k, v in self.options.items())


def _value(text: str) -> bool | int | float | str:
    lowered = text.lower()
    if lowered in ("true", "yes", "on"):
        return True
    if lowered in ("false", "no", "off"):
        return False
    try:
        return int(text, 0)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def parse_spec(spec: str) -> BusSpec:
    """Split a spec string into transport, channel and options.

    Parameters
    ----------
    spec : str
        ``TRANSPORT[:CHANNEL][,key=value...]``.

    Returns
    -------
    BusSpec
        The parsed spec.

    Raises
    ------
    BusSpecError
        An empty spec, a transport that is not a name, or an option that is not ``key=value``
        (naming the bad part).
    """
    if not isinstance(spec, str) or not spec.strip():
        raise BusSpecError(f"empty bus spec {spec!r}; expected e.g. 'virtual', 'socketcan:vcan0' "
                           "or 'socketcand:127.0.0.1:29536/can0'")
    head, *option_texts = spec.strip().split(",")
    transport, sep, channel = head.partition(":")
    if not _NAME.match(transport):
        raise BusSpecError(f"bus spec {spec!r}: {transport!r} is not a transport name")
    options: dict[str, bool | int | float | str] = {}
    for text in option_texts:
        key, eq, value = text.partition("=")
        key = key.strip()
        if not eq or not _NAME.match(key):
            raise BusSpecError(f"bus spec {spec!r}: option {text!r} is not key=value")
        options[key] = _value(value.strip())
    return BusSpec(transport=transport.lower(), channel=channel if sep and channel else None,
                   options=options)
