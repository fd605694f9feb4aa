"""Named signal traces with units, stored as one compressed ``.npz`` (plus CSV on request).

Rows are appended at a fixed channel order; each channel is kept in an ``array('d')`` so
appending costs no numpy call. ``traces.npz`` holds ``time_s`` and one array per channel; the
units are stored inside it as ``__units__`` (a JSON string) so the file stands alone.
"""

from __future__ import annotations

import csv
import json
from array import array
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hil.errors import HilError


class TraceError(HilError, ValueError):
    """A trace was declared twice, or a row does not fit the declared channels."""


class TraceSet:
    def __init__(self) -> None:
        self.names: list[str] = []
        self.units: dict[str, str] = {}
        self._time = array("d")
        self._columns: list[array[float]] = []

    def declare(self, name: str, unit: str) -> int:
        """Add a channel; returns its column index. Only before the first row."""
        if name in self.units:
            raise TraceError(f"trace {name!r} declared twice")
        if len(self._time):
            raise TraceError(f"trace {name!r} declared after rows were recorded")
        self.names.append(name)
        self.units[name] = unit
        self._columns.append(array("d"))
        return len(self.names) - 1

    def append(self, time_s: float, values: Sequence[float]) -> None:
        if len(values) != len(self._columns):
            raise TraceError(f"row has {len(values)} values for {len(self._columns)} traces")
        self._time.append(time_s)
        for column, value in zip(self._columns, values, strict=True):
            column.append(value)

    def __len__(self) -> int:
        return len(self._time)

    def arrays(self) -> dict[str, np.ndarray]:
        out = {"time_s": np.frombuffer(self._time, dtype=np.float64).copy()}
        for name, column in zip(self.names, self._columns, strict=True):
            out[name] = np.frombuffer(column, dtype=np.float64).copy()
        return out

    def save_npz(self, path: Path) -> Path:
        units = {"time_s": "s", **self.units}
        np.savez_compressed(path, __units__=np.array(json.dumps(units)), **self.arrays())
        return path

    def save_csv(self, path: Path) -> Path:
        arrays = self.arrays()
        with path.open("w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow([f"{name} [{unit}]" for name, unit in
                             [("time_s", "s"), *self.units.items()]])
            columns = [arrays["time_s"], *(arrays[n] for n in self.names)]
            for row in zip(*columns, strict=True):
                writer.writerow([repr(float(v)) for v in row])
        return path


def load_traces(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Read a ``traces.npz`` back: (arrays by name, units by name)."""
    with np.load(path) as data:
        units = json.loads(str(data["__units__"]))
        arrays = {k: data[k] for k in data.files if k != "__units__"}
    return arrays, units
