"""Figures of the field side: run ``python tests/hil/isobus/field/bench_field.py``.

Not a test (pytest does not collect it): it prints CPU times of one TC period
(``FieldTask.command`` + ``report`` on the example field, 4 sections, best of 3 drives),
of reading a 10,000-zone map with its overlap check, and of map lookups. It belongs under
``benchmarks/`` when the lead moves it there.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import box, mapping

from hil.isobus.field import (
    Boom,
    FieldTask,
    LocalFrame,
    load_field,
    load_prescription,
    prescription_from_geojson,
)

FIELDS = Path(__file__).resolve().parents[4] / "plant_emulators" / "fertilizer" / "fields"


def tc_period_ms() -> tuple[float, int]:
    """Best CPU ms of one 0.1 s TC period over the example field, and the periods driven."""
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    boom = Boom.uniform(4, 3.0, fore_aft_m=-1.0, turn_on_s=0.5, turn_off_s=0.3)
    times = np.arange(0.0, fld.path.duration_s, 0.1)
    best = float("inf")
    for _ in range(3):
        task = FieldTask(fld, rx, boom, rate_lookahead_s=0.43)
        t0 = time.process_time()
        for t in times:
            cmd = task.command(float(t))
            task.report(cmd.pose, cmd.sections_on, cmd.rates)
        best = min(best, (time.process_time() - t0) / times.size)
    return best * 1e3, times.size


def grid_map(n: int = 100, cell_m: float = 5.0) -> tuple[dict, LocalFrame]:
    """An n x n grid of square zones as a GeoJSON prescription."""
    frame = LocalFrame(116.3, 40.0)

    def unproject(c: np.ndarray) -> np.ndarray:
        return np.column_stack(frame.to_wgs84(c[:, 0], c[:, 1]))
    features = [{"type": "Feature", "properties": {"r": float(i + j)},
                 "geometry": mapping(shapely.transform(
                     box(i * cell_m, j * cell_m, (i + 1) * cell_m, (j + 1) * cell_m), unproject))}
                for i in range(n) for j in range(n)]
    return ({"type": "FeatureCollection", "features": features,
             "prescription": {"rate_property": "r", "unit": "kg/ha", "default_rate": 0}}, frame)


def main() -> None:
    ms, periods = tc_period_ms()
    print(f"FieldTask command + report: {ms:.2f} ms CPU per 0.1 s period "
          f"({periods} periods, 4 sections)")
    data, frame = grid_map()
    t0 = time.process_time()
    rx = prescription_from_geojson(data, frame=frame)
    print(f"10,000-zone map read and checked for overlaps: {time.process_time() - t0:.2f} s CPU")
    pts = np.random.default_rng(0).uniform(0.0, 500.0, (100_000, 2))
    t0 = time.process_time()
    rx.rate_at_local(pts[:, 0], pts[:, 1])
    print(f"lookup: {(time.process_time() - t0) / 1e5 * 1e6:.2f} us per point "
          "(100,000 points at once, 10,000 zones)")
    t0 = time.process_time()
    for k in range(1000):
        rx.rate_at_local(pts[k, 0], pts[k, 1])
    print(f"single-point lookup: {(time.process_time() - t0) / 1000 * 1e6:.0f} us")


if __name__ == "__main__":
    main()
