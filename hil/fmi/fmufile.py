"""An FMU on disk: its model description (fmpy), its validation, and its bus terminals.

fmpy reads and validates ``modelDescription.xml`` (its XML schemas, variable names, model
structure, units). What fmpy does not read is read here: ``terminalsAndIcons/
terminalsAndIcons.xml`` (validated against fmpy's own copy of the FMI 3.0 schema) and the
FMI-LS-BUS manifest (``extra/org.fmi-standard.fmi-ls-bus/fmi-ls-manifest.xml``). A **CAN
terminal** is a terminal of kind ``org.fmi-ls-bus.network-terminal`` whose ``Rx_Data`` and
``Tx_Data`` members are binaries of the LS-BUS CAN MIME type
(``application/org.fmi-standard.fmi-ls-bus.can``).
"""

from __future__ import annotations

import functools
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.errors import ConfigError

__all__ = ["CanTerminal", "FmuFile", "open_fmu", "validate"]

NETWORK_TERMINAL = "org.fmi-ls-bus.network-terminal"
CAN_MIME = "application/org.fmi-standard.fmi-ls-bus.can"
TERMINALS_XML = "terminalsAndIcons/terminalsAndIcons.xml"
LS_BUS_MANIFEST = "extra/org.fmi-standard.fmi-ls-bus/fmi-ls-manifest.xml"
LS_BUS_NAME = "org.fmi-standard.fmi-ls-bus"
BUS_NOTIFICATIONS = "org.fmi_standard.fmi_ls_bus.Can_BusNotifications"
#: the members a CAN terminal must have (LS-BUS 1.0, "Network abstraction")
CAN_MEMBERS = ("Rx_Data", "Tx_Data", "Rx_Clock", "Tx_Clock")


@dataclass(frozen=True)
class CanTerminal:
    """One CAN bus terminal of an FMU: its member variables' value references.

    Parameters
    ----------
    name : str
        The terminal's name (``CanChannel``).
    rx_data, tx_data, rx_clock, tx_clock : int
        Value references of its members.
    tx_clock_kind : str
        The ``Tx_Clock``'s ``intervalVariability``: ``triggered`` (the FMU says when) or a
        time-based one (``constant``, ``fixed``, ``tunable``, ``changing``, ``countdown``).
    tx_clock_interval : float or None
        A time-based ``Tx_Clock``'s ``intervalDecimal`` (s), when the description gives it.
    """

    name: str
    rx_data: int
    tx_data: int
    rx_clock: int
    tx_clock: int
    tx_clock_kind: str = "triggered"
    tx_clock_interval: float | None = None

    @property
    def tx_triggered(self) -> bool:
        """Whether the FMU triggers its ``Tx_Clock`` itself."""
        return self.tx_clock_kind == "triggered"


@dataclass(frozen=True)
class FmuFile:
    """A loaded FMU: the path, fmpy's model description, the unzipped directory, its terminals.

    Parameters
    ----------
    path : Path
        The ``.fmu`` file (or an unzipped FMU directory).
    description : fmpy.model_description.ModelDescription
        Its model description as fmpy reads it.
    can_terminals : tuple of CanTerminal
        Its CAN terminals.
    other_terminals : tuple of str
        Its other terminals' names (not CAN bus terminals).
    ls_bus : bool
        It ships the FMI-LS-BUS manifest.
    bus_notifications_vr : int or None
        The value reference of ``Can_BusNotifications``, if it declares one.
    variables : dict
        Its model variables by name.
    """

    path: Path
    description: Any
    can_terminals: tuple[CanTerminal, ...]
    other_terminals: tuple[str, ...]
    ls_bus: bool
    bus_notifications_vr: int | None
    variables: dict[str, Any] = field(repr=False)

    @property
    def fmi_major(self) -> int:
        """2 or 3."""
        return int(str(self.description.fmiVersion).split(".")[0])

    @property
    def model_identifier(self) -> str:
        return str(self.description.coSimulation.modelIdentifier)

    def variable(self, name: str) -> Any:
        """The model variable ``name`` (None when the FMU has none)."""
        return self.variables.get(name)


def _read_member(path: Path, member: str) -> bytes | None:
    if path.is_dir():
        target = path / member
        return target.read_bytes() if target.is_file() else None
    with zipfile.ZipFile(path) as zf:
        try:
            return zf.read(member)
        except KeyError:
            return None


@functools.lru_cache(maxsize=1)
def _terminals_schema() -> Any:
    """fmpy's copy of the FMI 3.0 ``fmi3TerminalsAndIcons.xsd`` (lxml)."""
    import fmpy
    from lxml import etree

    xsd = Path(os.path.dirname(fmpy.__file__)) / "schema" / "fmi3" / "fmi3TerminalsAndIcons.xsd"
    return etree.XMLSchema(file=str(xsd))


def _description_extras(path: Path) -> tuple[dict[str, str], dict[str, float]]:
    """What fmpy does not keep of the model description, by variable name.

    Binaries' ``mimeType`` and clocks' ``intervalDecimal``.
    """
    from lxml import etree

    raw = _read_member(path, "modelDescription.xml")
    if raw is None:
        return {}, {}
    root = etree.fromstring(raw)
    mimes = {el.get("name"): el.get("mimeType", "") for el in root.iter("Binary")}
    intervals = {el.get("name"): float(el.get("intervalDecimal"))
                 for el in root.iter("Clock") if el.get("intervalDecimal") is not None}
    return mimes, intervals


def _terminals(path: Path, variables: dict[str, Any], where: str
               ) -> tuple[tuple[CanTerminal, ...], tuple[str, ...]]:
    from lxml import etree

    raw = _read_member(path, TERMINALS_XML)
    if raw is None:
        return (), ()
    try:
        root = etree.fromstring(raw)
    except etree.XMLSyntaxError as exc:
        raise ConfigError(f"{TERMINALS_XML} is not XML: {exc}", path=where) from exc
    schema = _terminals_schema()
    if not schema.validate(root):
        first = schema.error_log[0] if schema.error_log else None
        detail = f"line {first.line}: {first.message}" if first is not None else "invalid"
        raise ConfigError(f"{TERMINALS_XML} does not follow the FMI 3.0 schema ({detail})",
                          path=where)
    mimes, intervals = _description_extras(path)
    can: list[CanTerminal] = []
    other: list[str] = []
    for term in root.iter("Terminal"):
        name = term.get("name", "")
        members = {m.get("memberName"): m.get("variableName")
                   for m in term.findall("TerminalMemberVariable")}
        is_can = (term.get("terminalKind") == NETWORK_TERMINAL and
                  mimes.get(members.get("Rx_Data") or "", "").startswith(CAN_MIME))
        if not is_can:
            if term.getparent() is not None and term.getparent().tag == "Terminals":
                other.append(name)
            continue
        missing = [m for m in CAN_MEMBERS if members.get(m) not in variables]
        if missing:
            raise ConfigError(f"CAN terminal {name!r} lacks the member(s) "
                              f"{', '.join(missing)} (or names variables the FMU does not "
                              f"declare)", path=where)
        tx_clock = variables[members["Tx_Clock"]]
        can.append(CanTerminal(
            name=name, rx_data=variables[members["Rx_Data"]].valueReference,
            tx_data=variables[members["Tx_Data"]].valueReference,
            rx_clock=variables[members["Rx_Clock"]].valueReference,
            tx_clock=tx_clock.valueReference,
            tx_clock_kind=str(tx_clock.intervalVariability or "triggered"),
            tx_clock_interval=intervals.get(members["Tx_Clock"])))
    return tuple(can), tuple(other)


def _ls_bus_manifest(path: Path, where: str) -> bool:
    from lxml import etree

    raw = _read_member(path, LS_BUS_MANIFEST)
    if raw is None:
        return False
    try:
        root = etree.fromstring(raw)
    except etree.XMLSyntaxError as exc:
        raise ConfigError(f"{LS_BUS_MANIFEST} is not XML: {exc}", path=where) from exc
    name = root.get("{http://fmi-standard.org/fmi-ls-manifest}fmi-ls-name")
    if name != LS_BUS_NAME:
        raise ConfigError(f"{LS_BUS_MANIFEST} names the layered standard {name!r}, not "
                          f"{LS_BUS_NAME!r}", path=where)
    if root.get("isBusSimulationFMU") == "true":
        raise ConfigError("the FMU is a bus simulation FMU (isBusSimulationFMU): agrihil is "
                          "the bus simulation; give it a node FMU", path=where)
    return True


def validate(path: str | Path) -> list[str]:
    """fmpy's validation of the FMU (schema, names, model structure, units): its problems
    (cached per file version: every profile load asks)."""
    p = Path(path)
    stat = p.stat()
    return list(_validate(str(p), stat.st_mtime_ns, stat.st_size))


@functools.lru_cache(maxsize=16)
def _validate(path: str, mtime_ns: int, size: int) -> tuple[str, ...]:
    from fmpy.validation import validate_fmu

    return tuple(validate_fmu(path))


@functools.lru_cache(maxsize=16)
def _open(path: str, mtime_ns: int, size: int) -> FmuFile:
    from fmpy import read_model_description

    p = Path(path)
    try:
        description = read_model_description(path, validate=True)
    except Exception as exc:  # fmpy raises ValidationError, zipfile's, lxml's ...
        problems = getattr(exc, "problems", None)
        text = "; ".join(problems[:3]) if problems else (str(exc) or type(exc).__name__)
        raise ConfigError(f"not a readable FMU: {' '.join(text.split())[:300]}",
                          path=path) from exc
    if description.coSimulation is None:
        raise ConfigError("the FMU has no co-simulation interface (agrihil steps it once "
                          "per control period with doStep)", path=path)
    variables = {v.name: v for v in description.modelVariables}
    can, other = _terminals(p, variables, path)
    ls_bus = _ls_bus_manifest(p, path)
    notif = variables.get(BUS_NOTIFICATIONS)
    return FmuFile(path=p, description=description, can_terminals=can, other_terminals=other,
                   ls_bus=ls_bus,
                   bus_notifications_vr=notif.valueReference if notif is not None else None,
                   variables=variables)


def open_fmu(path: str | Path) -> FmuFile:
    """Read an FMU (cached per file version).

    Raises
    ------
    ConfigError
        The file is missing, not an FMU fmpy can read, has no co-simulation interface, or its
        terminals or LS-BUS manifest are broken (naming the file).
    """
    p = Path(path)
    try:
        stat = p.stat()
    except OSError as exc:
        raise ConfigError(f"FMU not found ({exc.strerror or exc})", path=str(p)) from exc
    return _open(str(p), stat.st_mtime_ns, stat.st_size)
