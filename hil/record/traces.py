"""Named signal traces with units, stored as one compressed ``.npz`` (plus CSV on request).

Rows are appended at a fixed channel order into one flat, row-major ``array('d')`` (time, then
the channels): a row costs one ``append`` and one C-level ``extend``, no numpy call and no
per-channel Python loop; the columns are cut out with numpy when the traces are saved.
``traces.npz`` holds ``time_s`` and one array per channel; the units are stored inside it as
``__units__`` (a JSON string) so the file stands alone.
"""

from __future__ import annotations

import csv
import json
import zipfile
from array import array
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hil.errors import HilError


class TraceError(HilError, ValueError):
    """A trace was declared twice, or a row does not fit the declared channels."""


class TraceSet:
    """Named signal traces with units, one row per sample time; saved as ``traces.npz``.

    Declare the channels (:meth:`declare`), then append rows (:meth:`append`).
    """

    def __init__(self) -> None:
        self.names: list[str] = []
        self.units: dict[str, str] = {}
        #: every row, time first, then one value per channel
        self._data = array("d")
        self._rows = 0

    def declare(self, name: str, unit: str) -> int:
        """Add a channel; returns its column index. Only before the first row."""
        if name in self.units:
            raise TraceError(f"trace {name!r} declared twice")
        if self._rows:
            raise TraceError(f"trace {name!r} declared after rows were recorded")
        self.names.append(name)
        self.units[name] = unit
        return len(self.names) - 1

    def append(self, time_s: float, values: Sequence[float]) -> None:
        """Append one row: the time and one value per declared channel, in declaration order.

        Raises
        ------
        TraceError
            The row does not have one value per channel (nothing of it is kept).
        """
        width = len(self.names)
        if len(values) != width:
            raise TraceError(f"row has {len(values)} values for {width} traces")
        data = self._data
        try:
            data.append(time_s)
            data.extend(values)
        except BaseException:
            del data[self._rows * (width + 1):]          # never leave half a row behind
            raise
        self._rows += 1

    def __len__(self) -> int:
        return self._rows

    def arrays(self) -> dict[str, np.ndarray]:
        """The traces as arrays: ``time_s`` and one array per channel (copies)."""
        table = np.frombuffer(self._data, dtype=np.float64).reshape(self._rows,
                                                                    len(self.names) + 1)
        out = {"time_s": table[:, 0].copy()}
        for i, name in enumerate(self.names, start=1):
            out[name] = table[:, i].copy()
        return out

    def save_npz(self, path: Path) -> Path:
        """Write the traces and their units (``__units__``) to ``path``; returns it."""
        units = {"time_s": "s", **self.units}
        return write_npz(path, {"__units__": np.array(json.dumps(units)), **self.arrays()})

    def save_csv(self, path: Path) -> Path:
        """Write the traces as CSV to ``path``, one column ``name [unit]`` per trace; returns it."""
        arrays = self.arrays()
        with path.open("w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow([f"{name} [{unit}]" for name, unit in
                             [("time_s", "s"), *self.units.items()]])
            columns = [arrays["time_s"], *(arrays[n] for n in self.names)]
            for row in zip(*columns, strict=True):
                writer.writerow([repr(float(v)) for v in row])
        return path


def write_npz(path: Path, arrays: dict[str, np.ndarray], *, level: int = 1) -> Path:
    """Save ``arrays`` as a compressed ``.npz``, with deflate level ``level`` (default 1).

    What ``np.savez_compressed`` writes (a zip of ``.npy`` members written by
    ``np.lib.format.write_array``; ``np.load`` reads it the same way), with deflate level 1
    instead of zlib's default 6. Recorded signals are float64 that compress by a third either
    way; level 1 takes half the time or less, and saving sits on every run's critical path.
    """
    with zipfile.ZipFile(path, mode="w", compression=zipfile.ZIP_DEFLATED,
                         compresslevel=level) as archive:
        for name, value in arrays.items():
            with archive.open(f"{name}.npy", mode="w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)
    return path


def load_traces(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Read a ``traces.npz`` back: (arrays by name, units by name)."""
    with np.load(path) as data:
        units = json.loads(str(data["__units__"]))
        arrays = {k: data[k] for k in data.files if k != "__units__"}
    return arrays, units
