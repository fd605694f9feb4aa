"""Bindings: which frame of a database carries each rig quantity, and how.

A binding file (TOML) names a database and, per rig quantity, its carrier::

    rig = "fertilizer"
    database = "fertilizer.dbc"                     # relative to this file
    dut_node = "Controller"                         # the DUT's node in the database

    [quantities]
    target_flow = { message = "FertSetpoint", signal = "TargetFlow" }
    row_flow = { message = "FlowModule{row}", signal = "Flow" }       # one message per row
    # one multiplexed message for all rows: the multiplexer's value for rows 1, 2, ...
    row_window_mass = { message = "RowData", signal = "Mass", multiplexer = "Row",
                        rows = [0, 1, 2, 3] }
    mode = { message = "Cmd", signal = "Mode", values = { 0 = 2, 1 = 0, 2 = 1 } }
    ground_speed = { message = "Speed", signal = "Speed", unit = "km/h", cycle_ms = 50 }
    target_rate = { ddi = 6, element = 1 }          # ISO 11783-10 process data

Carriers:

* ``signal``: ``message`` (with ``{row}`` for one message per row, rows from 1) and
  ``signal`` of the database (``{row}`` too, for per-row signals of one message); ``unit``
  when the database declares none for the signal (a unit of :mod:`hil.contract.units`; the
  value is converted); ``values`` maps the quantity's values
  to the signal's (an enum, or a flag carried as an enum value); ``multiplexer`` and ``rows``
  for a multiplexed message; ``cycle_ms`` overrides the database's cycle time.
* ``ddi``: ISO 11783-10 process data, a device element and a DDI of the ISO 11783-11 table
  (:mod:`hil.isobus.ddi`), scaled by the DDI's resolution; ``element`` is one number or one
  per row.

Every error names the file and the key (``quantities.row_flow.message``).
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.contract.units import canonical
from hil.errors import ConfigError

__all__ = [
    "ROW_PLACEHOLDER",
    "Binding",
    "DdiCarrier",
    "SignalCarrier",
    "load_binding",
    "parse_binding",
]

ROW_PLACEHOLDER = "{row}"
_SIGNAL_KEYS = {"message", "signal", "unit", "values", "multiplexer", "rows", "cycle_ms"}
_DDI_KEYS = {"ddi", "element"}


@dataclass(frozen=True)
class SignalCarrier:
    """A quantity carried by a signal of a database message.

    Parameters
    ----------
    message : str
        The message's name; ``{row}`` in it stands for the row (from 1).
    signal : str
        The signal's name; ``{row}`` in it stands for the row (a multiplexed message whose
        rows have signals of their own, ``Flow_R1`` ... ``Flow_R4``).
    unit : str or None, optional
        The signal's unit when the database declares none.
    values : mapping of int to int, optional
        Quantity value → signal value (empty: the same number).
    multiplexer : str, optional
        The multiplexer signal of a multiplexed message carrying every row.
    rows : tuple of int, optional
        The multiplexer's value for row 1, 2, ...
    cycle_ms : float or None, optional
        Overrides the database's cycle time of the message.
    """

    message: str
    signal: str
    unit: str | None = None
    values: Mapping[int, int] = field(default_factory=dict)
    multiplexer: str = ""
    rows: tuple[int, ...] = ()
    cycle_ms: float | None = None

    kind = "signal"

    def message_for(self, row: int | None) -> str:
        """The message's name for ``row`` (None: a quantity that is not per row)."""
        if ROW_PLACEHOLDER in self.message:
            if row is None:
                raise ConfigError(f"{self.message!r} has {ROW_PLACEHOLDER} but the quantity "
                                  "is not per row", key="message")
            return self.message.replace(ROW_PLACEHOLDER, str(row))
        return self.message

    def signal_for(self, row: int | None) -> str:
        """The signal's name for ``row`` (``{row}`` in it stands for the row, from 1)."""
        if ROW_PLACEHOLDER in self.signal:
            if row is None:
                raise ConfigError(f"{self.signal!r} has {ROW_PLACEHOLDER} but the quantity "
                                  "is not per row", key="signal")
            return self.signal.replace(ROW_PLACEHOLDER, str(row))
        return self.signal

    def mux_value(self, row: int | None) -> int | None:
        """The multiplexer's value for ``row`` (None without a multiplexer)."""
        if not self.multiplexer:
            return None
        if row is None:
            return self.rows[0]
        if not 1 <= row <= len(self.rows):
            raise ConfigError(f"no multiplexer value for row {row} (rows = {list(self.rows)})",
                              key="rows")
        return self.rows[row - 1]

    def describe(self) -> str:
        """``Message.Signal`` with its rule, for messages and the docs."""
        text = f"{self.message}.{self.signal}"
        if self.multiplexer:
            text += f" (multiplexer {self.multiplexer} = {list(self.rows)})"
        return text


@dataclass(frozen=True)
class DdiCarrier:
    """A quantity carried as ISO 11783-10 process data.

    Parameters
    ----------
    ddi : int
        The data dictionary identifier (ISO 11783-11).
    element : tuple of int
        The device element number (one, or one per row).
    """

    ddi: int
    element: tuple[int, ...]

    kind = "ddi"

    def element_for(self, row: int | None) -> int:
        """The device element of ``row`` (the only one when not per row)."""
        if row is None or len(self.element) == 1:
            return self.element[0]
        return self.element[row - 1]

    def describe(self) -> str:
        """``DDI n, element e``."""
        return f"DDI {self.ddi}, element {'/'.join(str(e) for e in self.element)}"


Carrier = SignalCarrier | DdiCarrier


@dataclass(frozen=True)
class Binding:
    """Quantities → carriers, with the database they refer to.

    Parameters
    ----------
    rig : str
        The rig whose quantities it binds.
    database : Path
        The database file (absolute).
    carriers : mapping of str to carrier
        By quantity name.
    path : Path or None
        The binding file (None: a profile's inline ``[binding]``).
    source : str
        Where it came from, for errors (a file, or ``profile.toml [binding]``).
    dut_node : str, optional
        The DUT's node name in the database (the sender of the frames it owns), when the
        rig's default name does not apply.
    """

    rig: str
    database: Path
    carriers: Mapping[str, Carrier]
    path: Path | None = None
    source: str = ""
    dut_node: str = ""

    def signal_carriers(self) -> dict[str, SignalCarrier]:
        """The quantities carried by database signals."""
        return {k: c for k, c in self.carriers.items() if isinstance(c, SignalCarrier)}


def load_binding(path: str | Path) -> Binding:
    """Read a binding file.

    Raises
    ------
    ConfigError
        Missing or invalid file, unknown key or bad carrier (naming the file and the key).
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise ConfigError("binding file not found", path=str(path)) from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read the binding: {exc}", path=str(path)) from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=str(path)) from exc
    return parse_binding(data, source=str(path), base=path.resolve().parent, path=path)


def parse_binding(data: Mapping[str, Any], *, source: str, base: Path,
                  path: Path | None = None, prefix: str = "") -> Binding:
    """A binding from its TOML table.

    Parameters
    ----------
    data : mapping
        ``rig``, ``database`` and ``quantities``.
    source : str
        The file named in errors.
    base : Path
        The directory a relative ``database`` is resolved against.
    path : Path, optional
        The binding file.
    prefix : str, optional
        Prepended to key names in errors (``"binding."`` for a profile's inline table).

    Raises
    ------
    ConfigError
        Naming ``source`` and the key.
    """
    def error(message: str, key: str) -> ConfigError:
        return ConfigError(message, path=source, key=prefix + key)

    if not isinstance(data, Mapping):
        raise error("expected a table", "")
    unknown = sorted(set(data) - {"rig", "database", "dut_node", "quantities"})
    if unknown:
        raise error("unknown key (known: rig, database, dut_node, quantities)", unknown[0])
    rig = data.get("rig")
    if not isinstance(rig, str) or not rig:
        raise error("expected the rig's name", "rig")
    database = data.get("database")
    if not isinstance(database, str) or not database:
        raise error("expected the database file (relative to the binding)", "database")
    db_path = Path(database)
    if not db_path.is_absolute():
        db_path = (base / db_path).resolve()
    dut_node = data.get("dut_node", "")
    if not isinstance(dut_node, str):
        raise error("expected the DUT's node name in the database", "dut_node")
    quantities = data.get("quantities", {})
    if not isinstance(quantities, Mapping):
        raise error("expected a table of quantity = carrier", "quantities")
    carriers: dict[str, Carrier] = {}
    for name, spec in quantities.items():
        carriers[name] = _carrier(spec, f"quantities.{name}", error)
    return Binding(rig=rig.replace("-", "_"), database=db_path, carriers=carriers, path=path,
                   source=source, dut_node=dut_node)


def _carrier(spec: Any, key: str, error: Any) -> Carrier:
    if not isinstance(spec, Mapping):
        raise error("expected a table: { message = ..., signal = ... } or "
                    "{ ddi = ..., element = ... }", key)
    if "ddi" in spec:
        unknown = sorted(set(spec) - _DDI_KEYS)
        if unknown:
            raise error(f"unknown key of a ddi carrier (known: {', '.join(sorted(_DDI_KEYS))})",
                        f"{key}.{unknown[0]}")
        ddi = spec["ddi"]
        if not _is_int(ddi) or not 0 <= ddi <= 0xFFFE:
            raise error(f"a DDI is 0..65534, got {ddi!r}", f"{key}.ddi")
        element = spec.get("element", 0)
        elements = tuple(element) if isinstance(element, list) else (element,)
        if not elements or not all(_is_int(e) and 0 <= e <= 4095 for e in elements):
            raise error(f"an element number is 0..4095 (or a list, one per row), got "
                        f"{element!r}", f"{key}.element")
        return DdiCarrier(ddi=ddi, element=elements)
    unknown = sorted(set(spec) - _SIGNAL_KEYS)
    if unknown:
        raise error(f"unknown key (known: {', '.join(sorted(_SIGNAL_KEYS | {'ddi'}))})",
                    f"{key}.{unknown[0]}")
    for required in ("message", "signal"):
        if not isinstance(spec.get(required), str) or not spec.get(required):
            raise error(f"expected the {required}'s name", f"{key}.{required}")
    unit = spec.get("unit")
    if unit is not None:
        if not isinstance(unit, str):
            raise error(f"expected a unit, got {unit!r}", f"{key}.unit")
        try:
            canonical(unit)
        except ConfigError as exc:
            raise error(str(exc).removeprefix("[unit] "), f"{key}.unit") from None
    values_spec = spec.get("values", {})
    if not isinstance(values_spec, Mapping):
        raise error("expected { quantity value = signal value, ... }", f"{key}.values")
    values: dict[int, int] = {}
    for k, v in values_spec.items():
        try:
            q_value = int(k)
        except ValueError:
            raise error(f"a quantity value is an integer, got {k!r}",
                        f"{key}.values") from None
        if not _is_int(v):
            raise error(f"a signal value is an integer, got {v!r}", f"{key}.values.{k}")
        values[q_value] = v
    if len(set(values.values())) != len(values):
        raise error("two quantity values map to one signal value (the rig could not decode "
                    "it)", f"{key}.values")
    multiplexer = spec.get("multiplexer", "")
    rows = spec.get("rows", [])
    if not isinstance(multiplexer, str):
        raise error("expected the multiplexer signal's name", f"{key}.multiplexer")
    if not isinstance(rows, list) or not all(_is_int(r) for r in rows):
        raise error("expected the multiplexer value of each row, [row 1, row 2, ...]",
                    f"{key}.rows")
    if bool(multiplexer) != bool(rows):
        raise error("multiplexer and rows go together", f"{key}.multiplexer")
    if len(set(rows)) != len(rows):
        raise error(f"two rows share a multiplexer value: {rows}", f"{key}.rows")
    if multiplexer and ROW_PLACEHOLDER in spec["message"]:
        raise error("one message per row ({row}) or a multiplexer, not both",
                    f"{key}.multiplexer")
    cycle = spec.get("cycle_ms")
    if cycle is not None and (not isinstance(cycle, int | float) or isinstance(cycle, bool)
                              or not 0 < cycle <= 60000):
        raise error(f"a cycle time is 0 < ms <= 60000, got {cycle!r}", f"{key}.cycle_ms")
    return SignalCarrier(message=spec["message"], signal=spec["signal"], unit=unit,
                         values=values, multiplexer=multiplexer, rows=tuple(rows),
                         cycle_ms=float(cycle) if cycle is not None else None)


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)
