"""ISO 11783-10 TASKDATA grid prescriptions (``GRD`` types 1 and 2) as a :class:`PrescriptionMap`.

A task (``TSK``) of ``TASKDATA.XML`` may carry one grid (``GRD``): a rectangle of cells in WGS84
degrees, south-west corner at (``B`` = GridMinimumEastPosition, ``A`` = GridMinimumNorthPosition),
cells ``D`` x ``C`` degrees (east x north), ``E`` columns and ``F`` rows, stored in the binary
file named by ``G`` (plus ``.BIN``) row by row from the southern row, columns west to east:

- **type 1**: one byte per cell, the code of a treatment zone (``TZN``, attribute ``A``) whose
  process data variables (``PDV``: ``A`` the DDI in hex, ``B`` the value in the DDI's raw units)
  hold the rates;
- **type 2**: per cell, one little-endian int32 per process data variable of the treatment zone
  that ``J`` names, in that zone's ``PDV`` order: the rates themselves, raw DDI units.

The rate read is the one of the set-point DDI of ``unit`` (DDI 6 for ``kg/ha``, DDI 1 for
``l/ha``), converted to the map unit. Outside the grid the task's out-of-field treatment zone
(``TSK`` ``J``) gives the rate, else its default zone (``H``), else the caller's
``default_rate``; with none of them the task is refused (never read as 0).

Attribute letters and the cell order follow ISO 11783-10 as the isoxml (Python) and ADAPT ISOv4
plugin libraries implement it; the tests build grids by these rules and read them back, and
check the orientation with a grid that is not symmetric. No third-party TASKDATA file was
available to check against.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from shapely.geometry import box

from hil.errors import ConfigError
from hil.isobus.field.geodesy import LocalFrame
from hil.isobus.field.prescription import RATE_UNITS, PrescriptionMap, Zone, _to_local

__all__ = ["load_taskdata_grid"]


def _attr(elem: ET.Element, key: str, source: str, where: str, kind: type = float) -> float:
    raw = elem.get(key)
    if raw is None:
        raise ConfigError(f"missing attribute {key}", path=source, key=where)
    try:
        return kind(raw)
    except ValueError:
        raise ConfigError(f"attribute {key}={raw!r} is not a {kind.__name__}", path=source,
                          key=where) from None


def _zone_values(tzn: ET.Element, source: str, where: str) -> list[tuple[int, int]]:
    """(DDI, raw value) of each PDV of a treatment zone, in order."""
    out = []
    for i, pdv in enumerate(tzn.findall("PDV")):
        key = f"{where}/PDV[{i}]"
        ddi_text = pdv.get("A")
        try:
            ddi = int(ddi_text or "", 16)
        except ValueError:
            raise ConfigError(f"DDI {ddi_text!r} is not hexadecimal", path=source,
                              key=key) from None
        out.append((ddi, int(_attr(pdv, "B", source, key, int))))
    return out


def _find_task(root: ET.Element, task_id: str | None, source: str) -> ET.Element:
    tasks = [t for t in root.findall("TSK") if t.find("GRD") is not None]
    if task_id is not None:
        tasks = [t for t in tasks if t.get("A") == task_id]
        if not tasks:
            raise ConfigError(f"no task {task_id!r} with a grid", path=source, key="TSK")
    if not tasks:
        raise ConfigError("no task with a grid (GRD)", path=source, key="TSK")
    if len(tasks) > 1:
        ids = ", ".join(str(t.get("A")) for t in tasks)
        raise ConfigError(f"several tasks with a grid ({ids}): name one", path=source, key="TSK")
    return tasks[0]


def load_taskdata_grid(path: str | Path, *, unit: str = "kg/ha", task_id: str | None = None,
                       default_rate: float | None = None,
                       frame: LocalFrame | None = None) -> PrescriptionMap:
    """Read the grid of a TASKDATA task as a prescription map (one zone per cell).

    Parameters
    ----------
    path : path
        ``TASKDATA.XML``, or the directory holding it (the grid's binary file lies beside it).
    unit : str
        ``kg/ha`` (DDI 6) or ``l/ha`` (DDI 1): which set-point to read.
    task_id : str, optional
        The task (``TSK`` ``A``) when several have a grid.
    default_rate : float, optional
        The rate outside the grid when the task names no out-of-field or default zone.
    frame : LocalFrame, optional
        The plane to look up in; by default centred on the grid.

    Raises
    ------
    ConfigError
        Naming the file and the element: unreadable XML or binary file, a missing attribute,
        a binary file of the wrong length, a cell code with no treatment zone, a zone without
        the unit's DDI, no rate for outside the grid.
    """
    xml_path = Path(path)
    if xml_path.is_dir():
        xml_path = xml_path / "TASKDATA.XML"
    source = str(xml_path)
    if unit not in RATE_UNITS:
        raise ConfigError(f"unit {unit!r} is not one of {', '.join(RATE_UNITS)}", path=source)
    rate_unit = RATE_UNITS[unit]
    try:
        root = ET.parse(xml_path).getroot()
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", path=source) from None
    except ET.ParseError as exc:
        raise ConfigError(f"not XML: {exc}", path=source) from None
    task = _find_task(root, task_id, source)
    tkey = f"TSK[A={task.get('A')}]"
    zones: dict[int, list[tuple[int, int]]] = {}
    for i, tzn in enumerate(task.findall("TZN")):
        where = f"{tkey}/TZN[{i}]"
        zones[int(_attr(tzn, "A", source, where, int))] = _zone_values(tzn, source, where)

    def zone_rate(code: int, where: str) -> float:
        if code not in zones:
            raise ConfigError(f"treatment zone {code} is not defined", path=source, key=where)
        for ddi, value in zones[code]:
            if ddi == rate_unit.ddi:
                return value / rate_unit.ddi_per_unit
        raise ConfigError(f"treatment zone {code} has no DDI {rate_unit.ddi} ({unit}) value",
                          path=source, key=where)

    grd = task.find("GRD")
    assert grd is not None
    gkey = f"{tkey}/GRD"
    south = _attr(grd, "A", source, gkey)
    west = _attr(grd, "B", source, gkey)
    dlat = _attr(grd, "C", source, gkey)
    dlon = _attr(grd, "D", source, gkey)
    cols = int(_attr(grd, "E", source, gkey, int))
    rows = int(_attr(grd, "F", source, gkey, int))
    grid_type = int(_attr(grd, "I", source, gkey, int))
    name = grd.get("G")
    if not name:
        raise ConfigError("missing attribute G (file name)", path=source, key=gkey)
    if not (0 < dlat <= 1 and 0 < dlon <= 1 and cols > 0 and rows > 0):
        raise ConfigError("cell sizes must be in (0, 1] degrees and the grid not empty",
                          path=source, key=gkey)
    candidates = [p for p in xml_path.parent.iterdir() if p.name.upper() == f"{name.upper()}.BIN"]
    if not candidates:
        raise ConfigError(f"grid file {name}.BIN not found beside the XML", path=source,
                          key=gkey)
    bin_path = candidates[0]
    data = bin_path.read_bytes()

    if grid_type == 1:
        expected = rows * cols
        if len(data) != expected:
            raise ConfigError(f"{len(data)} bytes, expected {expected} ({rows} rows x {cols} "
                              "columns of 1 byte)", path=str(bin_path))
        codes = np.frombuffer(data, dtype=np.uint8).reshape(rows, cols)
        table = {int(c): zone_rate(int(c), f"{bin_path.name}: cell code {int(c)}")
                 for c in np.unique(codes)}
        rates = np.vectorize(table.__getitem__, otypes=[float])(codes)
    elif grid_type == 2:
        code = int(_attr(grd, "J", source, gkey, int))
        if code not in zones:
            raise ConfigError(f"treatment zone {code} is not defined", path=source, key=gkey)
        ddis = [ddi for ddi, _ in zones[code]]
        if rate_unit.ddi not in ddis:
            raise ConfigError(f"treatment zone {code} has no DDI {rate_unit.ddi} ({unit})",
                              path=source, key=gkey)
        expected = rows * cols * 4 * len(ddis)
        if len(data) != expected:
            raise ConfigError(f"{len(data)} bytes, expected {expected} ({rows} rows x {cols} "
                              f"columns x {len(ddis)} int32)", path=str(bin_path))
        values = np.frombuffer(data, dtype="<i4").reshape(rows, cols, len(ddis))
        rates = values[:, :, ddis.index(rate_unit.ddi)] / rate_unit.ddi_per_unit
    else:
        raise ConfigError(f"grid type {grid_type} is not 1 or 2", path=source, key=gkey)

    outside = None
    for attr in ("J", "H"):   # out-of-field zone, then the default zone
        if task.get(attr) is not None:
            outside = zone_rate(int(_attr(task, attr, source, tkey, int)), f"{tkey}@{attr}")
            break
    if outside is None:
        if default_rate is None:
            raise ConfigError("no rate outside the grid: the task names no out-of-field (J) or "
                              "default (H) treatment zone, and none was given", path=source,
                              key=tkey)
        outside = float(default_rate)

    if frame is None:
        frame = LocalFrame(west + cols * dlon / 2.0, south + rows * dlat / 2.0)
    cells = []
    for r in range(rows):
        for c in range(cols):
            cell = box(west + c * dlon, south + r * dlat, west + (c + 1) * dlon,
                       south + (r + 1) * dlat)
            cells.append(Zone(r * cols + c, f"{name} row {r} col {c}", float(rates[r, c]), cell,
                              _to_local(cell, frame)))
    return PrescriptionMap(tuple(cells), outside, rate_unit, f"DDI {rate_unit.ddi}", frame,
                           source)
