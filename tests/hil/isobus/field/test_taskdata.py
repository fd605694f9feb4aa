"""TASKDATA grids (ISO 11783-10 GRD types 1 and 2) read as prescription maps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.errors import ConfigError
from hil.isobus.field.taskdata import load_taskdata_grid

SOUTH, WEST, CELL = 40.0, 116.3, 0.0001
# rows from the south; deliberately not symmetric, so a flipped or transposed read shows
CODES = np.array([[1, 1, 2, 2],
                  [1, 3, 3, 2],
                  [3, 3, 3, 3]], dtype=np.uint8)
KG_HA = {0: 0.0, 1: 160.0, 2: 240.0, 3: 200.0}


def _xml(grid: str, zones: str, task_attrs: str = 'J="0"', extra: str = "") -> str:
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ISO11783_TaskData VersionMajor="4" '
            f'VersionMinor="2" DataTransferOrigin="1">\n<TSK A="TSK1" B="rates" G="1" '
            f'{task_attrs}>\n{zones}{grid}</TSK>\n{extra}</ISO11783_TaskData>\n')


def _zone(code: int, *pdvs: tuple[int, int]) -> str:
    inner = "".join(f'<PDV A="{ddi:04X}" B="{value}"/>' for ddi, value in pdvs)
    return f'<TZN A="{code}" B="zone {code}">{inner}</TZN>\n'


def _grid(kind: int, extra: str = "") -> str:
    return (f'<GRD A="{SOUTH}" B="{WEST}" C="{CELL}" D="{CELL}" E="4" F="3" G="GRD00001" '
            f'I="{kind}" {extra}/>\n')


def _type1(tmp_path: Path, **kw: str) -> Path:
    zones = "".join(_zone(c, (6, int(r * 100)), (1, 5)) for c, r in KG_HA.items())
    (tmp_path / "TASKDATA.XML").write_text(_xml(_grid(1), zones, **kw), encoding="utf-8")
    (tmp_path / "GRD00001.BIN").write_bytes(CODES.tobytes())
    return tmp_path


def _centre(rx, row: int, col: int) -> float:  # type: ignore[no-untyped-def]
    lon, lat = WEST + (col + 0.5) * CELL, SOUTH + (row + 0.5) * CELL
    return float(rx.rate_at(lon, lat))


def test_type_1_cells_take_their_zones_rates(tmp_path: Path) -> None:
    rx = load_taskdata_grid(_type1(tmp_path))
    got = [[_centre(rx, r, c) for c in range(4)] for r in range(3)]
    assert got == [[KG_HA[int(code)] for code in row] for row in CODES]
    assert float(rx.rate_at(WEST - CELL, SOUTH)) == 0.0          # out-of-field zone 0
    assert len(rx.zones) == 12 and rx.unit.ddi == 6


def test_type_2_reads_the_units_layer(tmp_path: Path) -> None:
    kg = np.array([[150, 160, 170, 180], [190, 200, 210, 220], [230, 240, 250, 260]])
    litres = np.full_like(kg, 7)
    values = np.stack([litres * 10_000, kg * 100], axis=-1).astype("<i4")  # PDV order: 1, 6
    zones = _zone(9, (1, 0), (6, 0)) + _zone(0, (1, 0), (6, 0))
    (tmp_path / "TASKDATA.XML").write_text(_xml(_grid(2, 'J="9"'), zones), encoding="utf-8")
    (tmp_path / "grd00001.bin").write_bytes(values.tobytes())   # case of the name differs
    rx = load_taskdata_grid(tmp_path / "TASKDATA.XML")
    assert [[_centre(rx, r, c) for c in range(4)] for r in range(3)] == kg.tolist()
    vol = load_taskdata_grid(tmp_path, unit="l/ha")
    assert _centre(vol, 2, 3) == 7.0 and vol.unit.ddi == 1


def test_a_binary_file_of_the_wrong_length_is_refused(tmp_path: Path) -> None:
    _type1(tmp_path)
    (tmp_path / "GRD00001.BIN").write_bytes(CODES.tobytes()[:-1])
    with pytest.raises(ConfigError, match=r"GRD00001.BIN: 11 bytes, expected 12"):
        load_taskdata_grid(tmp_path)


def test_a_cell_without_a_zone_is_refused(tmp_path: Path) -> None:
    _type1(tmp_path)
    codes = CODES.copy()
    codes[1, 1] = 7
    (tmp_path / "GRD00001.BIN").write_bytes(codes.tobytes())
    with pytest.raises(ConfigError, match=r"cell code 7\] treatment zone 7 is not defined"):
        load_taskdata_grid(tmp_path)


def test_outside_the_grid_needs_a_stated_rate(tmp_path: Path) -> None:
    _type1(tmp_path, task_attrs="")
    with pytest.raises(ConfigError, match=r"TSK\[A=TSK1\]\] no rate outside the grid"):
        load_taskdata_grid(tmp_path)
    rx = load_taskdata_grid(tmp_path, default_rate=55.0)
    assert float(rx.rate_at(WEST - CELL, SOUTH)) == 55.0
    _type1(tmp_path, task_attrs='H="3"')                       # the default zone
    assert float(load_taskdata_grid(tmp_path).rate_at(WEST - CELL, SOUTH)) == 200.0


def test_tasks_and_files_that_cannot_be_read(tmp_path: Path) -> None:
    second = '<TSK A="TSK2" G="1"><GRD A="40" B="116" C="0.1" D="0.1" E="1" F="1" ' \
             'G="GRD00002" I="1"/></TSK>\n'
    _type1(tmp_path, extra=second)
    with pytest.raises(ConfigError, match="several tasks with a grid"):
        load_taskdata_grid(tmp_path)
    assert len(load_taskdata_grid(tmp_path, task_id="TSK1").zones) == 12
    (tmp_path / "TASKDATA.XML").write_text("<ISO11783_TaskData>", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"TASKDATA\.XML: not XML"):
        load_taskdata_grid(tmp_path)
    with pytest.raises(ConfigError, match="cannot read"):
        load_taskdata_grid(tmp_path / "missing")
