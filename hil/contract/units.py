"""The units a binding may convert between: a small table of dimensions and factors.

A rig quantity has a unit (``g/s``, ``kg/hm2``, ``m/s``, ``mV`` …); the DUT's database may carry
it in another unit of the same dimension (``kg/h``, ``kg/ha``, ``km/h``, ``V``). The conversion
is one factor: ``value_in_b = value_in_a * factor(a, b)``. Only linear units without offset are
listed (no °C/°F): a carrier's own offset is the database's business, applied by cantools.

Units are matched exactly after whitespace removal and a few spellings (``r/min`` = ``rpm``,
``ha`` = ``hm2``, ``²`` = ``2``, ``³`` = ``3``), so ``"kg/ha"``, ``"kg / ha"`` and ``"kg/hm²"``
are one unit.

Example
-------
>>> factor("g/s", "kg/h")
3.6
>>> convert(2.0, "km/h", "m/s")  # doctest: +ELLIPSIS
0.555...
"""

from __future__ import annotations

from hil.errors import ConfigError

__all__ = ["UNITS", "canonical", "convert", "dimension", "factor", "same_unit"]

#: unit → (dimension, value of one unit in the dimension's base unit)
UNITS: dict[str, tuple[str, float]] = {
    # mass flow (base g/s)
    "g/s": ("mass flow", 1.0), "kg/s": ("mass flow", 1000.0), "mg/s": ("mass flow", 1e-3),
    "g/min": ("mass flow", 1.0 / 60.0), "kg/min": ("mass flow", 1000.0 / 60.0),
    "kg/h": ("mass flow", 1000.0 / 3600.0), "t/h": ("mass flow", 1e6 / 3600.0),
    # mass per area (base kg/hm2 = kg/ha)
    "kg/hm2": ("mass per area", 1.0), "kg/ha": ("mass per area", 1.0),
    "t/ha": ("mass per area", 1000.0), "g/m2": ("mass per area", 10.0),
    "mg/m2": ("mass per area", 0.01), "kg/m2": ("mass per area", 10000.0),
    # volume per area (base mm3/m2, ISO 11783-11) and volume flow (base mm3/s)
    "mm3/m2": ("volume per area", 1.0), "l/ha": ("volume per area", 100.0),
    "L/ha": ("volume per area", 100.0), "ml/m2": ("volume per area", 1000.0),
    "mm3/s": ("volume flow", 1.0), "l/h": ("volume flow", 1e6 / 3600.0),
    "L/h": ("volume flow", 1e6 / 3600.0), "l/min": ("volume flow", 1e6 / 60.0),
    "L/min": ("volume flow", 1e6 / 60.0),
    # mass (base g)
    "g": ("mass", 1.0), "kg": ("mass", 1000.0), "mg": ("mass", 1e-3), "t": ("mass", 1e6),
    # mass per revolution (base g/rev: a meter's calibration)
    "g/rev": ("mass per revolution", 1.0), "kg/rev": ("mass per revolution", 1000.0),
    # length (base m)
    "m": ("length", 1.0), "mm": ("length", 1e-3), "cm": ("length", 1e-2), "km": ("length", 1e3),
    "um": ("length", 1e-6), "µm": ("length", 1e-6),
    # speed (base m/s)
    "m/s": ("speed", 1.0), "km/h": ("speed", 1.0 / 3.6), "mm/s": ("speed", 1e-3),
    "cm/s": ("speed", 1e-2),
    # time (base s)
    "s": ("time", 1.0), "ms": ("time", 1e-3), "us": ("time", 1e-6), "µs": ("time", 1e-6),
    "min": ("time", 60.0), "h": ("time", 3600.0),
    # voltage (base V)
    "V": ("voltage", 1.0), "mV": ("voltage", 1e-3),
    # current (base A)
    "A": ("current", 1.0), "mA": ("current", 1e-3),
    # rotational speed (base r/min)
    "rpm": ("rotational speed", 1.0), "r/s": ("rotational speed", 60.0),
    "rad/s": ("rotational speed", 60.0 / (2.0 * 3.141592653589793)),
    # angle (base deg)
    "deg": ("angle", 1.0), "°": ("angle", 1.0), "rad": ("angle", 180.0 / 3.141592653589793),
    "mdeg": ("angle", 1e-3),
    # frequency (base Hz)
    "Hz": ("frequency", 1.0), "kHz": ("frequency", 1e3),
    # ratios and counts (base 1)
    "": ("dimensionless", 1.0), "1": ("dimensionless", 1.0), "%": ("dimensionless", 0.01),
    "rows": ("count", 1.0), "pulses": ("count", 1.0), "#": ("count", 1.0),
}

_SPELLINGS = {"r/min": "rpm", "1/min": "rpm", "ha": "hm2", "²": "2", "³": "3",
              "sec": "s", "kph": "km/h", "mps": "m/s", "volt": "V", "counts": "#"}


def canonical(unit: str | None) -> str:
    """The table's spelling of ``unit`` (whitespace removed, common spellings folded).

    Raises
    ------
    ConfigError
        The unit is not in :data:`UNITS`.
    """
    text = "".join((unit or "").split())
    if text in UNITS:
        return text
    for old, new in _SPELLINGS.items():
        text = text.replace(old, new)
    if text in UNITS:
        return text
    raise ConfigError(f"unknown unit {unit!r} (known: "
                      f"{', '.join(repr(u) for u in UNITS if u)})", key="unit")


def dimension(unit: str | None) -> str:
    """What ``unit`` measures (``"mass flow"``, ``"speed"`` …)."""
    return UNITS[canonical(unit)][0]


def same_unit(a: str | None, b: str | None) -> bool:
    """Whether ``a`` and ``b`` are one unit (conversion factor exactly 1)."""
    try:
        return factor(a, b) == 1.0
    except ConfigError:
        return False


def factor(from_unit: str | None, to_unit: str | None) -> float:
    """The factor that turns a value in ``from_unit`` into ``to_unit``.

    Raises
    ------
    ConfigError
        A unit is unknown or the two measure different things.
    """
    a, b = canonical(from_unit), canonical(to_unit)
    if a == b:
        return 1.0
    dim_a, scale_a = UNITS[a]
    dim_b, scale_b = UNITS[b]
    if dim_a != dim_b and {dim_a, dim_b} != {"dimensionless", "count"}:
        raise ConfigError(f"cannot convert {from_unit!r} ({dim_a}) to {to_unit!r} ({dim_b})",
                          key="unit")
    return scale_a / scale_b


def convert(value: float, from_unit: str | None, to_unit: str | None) -> float:
    """``value`` in ``from_unit`` expressed in ``to_unit``."""
    return value * factor(from_unit, to_unit)
