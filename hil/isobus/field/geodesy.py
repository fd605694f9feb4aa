"""WGS84 longitude/latitude to a local east/north plane in metres, and back.

A :class:`LocalFrame` is the local tangent plane at a reference point on the WGS84 ellipsoid:
a point is turned into Earth-centred Earth-fixed (ECEF) coordinates, then rotated into the
east/north/up axes of the reference point, and ``up`` is dropped (an orthographic projection
onto the tangent plane). The inverse finds the point at the reference height whose east/north
are those given (three fixed-point steps on the height; they converge to < 1 nm within 10 km).

How large a field it is good for
--------------------------------
The projection shortens a distance ``s`` from the reference point by about ``s³ / (6 R²)``
(R ≈ 6,371 km) and distances between two points by the same order. Measured against Vincenty's
inverse formula on the ellipsoid (``tests/hil/isobus/field/test_geodesy.py``; Vincenty is
accurate to 0.5 mm), at latitudes 0°, 45° and 70°, between random points of a square about the
reference point: the plane distance differs from the geodesic one by at most 0.02 mm in a
2 km x 2 km field, 0.22 mm in 5 km x 5 km, 1.8 mm in 10 km x 10 km and 0.3 m in 50 km x 50 km.
Up to 10 km that is far below a GNSS receiver's error (RTK: ~2 cm), so any field a planter
drives (a few km across at most) is fine; for a region tens of km across use a projected CRS.
Coordinates are good near the poles too (ECEF has no singularity there), but a frame must not
be centred on a pole, where east and north are undefined.

The round trip lon/lat -> plane -> lon/lat returns the input to < 1e-9 degrees (0.1 mm).

>>> frame = LocalFrame(lon0_deg=116.3, lat0_deg=40.0)
>>> e, n = frame.to_local(116.3 + 0.001, 40.0)
>>> round(float(e), 2), round(float(n), 3)      # one thousandth of a degree east at 40° N
(85.39, 0.0)
>>> lon, lat = frame.to_wgs84(e, n)
>>> round(float(lon), 9), round(float(lat), 9)
(116.301, 40.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["WGS84_A_M", "WGS84_F", "LocalFrame", "ecef_to_geodetic", "geodetic_to_ecef"]

WGS84_A_M = 6_378_137.0
"""Semi-major axis of the WGS84 ellipsoid, m."""
WGS84_F = 1.0 / 298.257_223_563
"""Flattening of the WGS84 ellipsoid."""
_E2 = WGS84_F * (2.0 - WGS84_F)


def geodetic_to_ecef(lon_deg: ArrayLike, lat_deg: ArrayLike,
                     h_m: ArrayLike = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Earth-centred Earth-fixed X, Y, Z (m) of WGS84 longitude, latitude (degrees), height (m)."""
    lon = np.radians(np.asarray(lon_deg, dtype=float))
    lat = np.radians(np.asarray(lat_deg, dtype=float))
    h = np.asarray(h_m, dtype=float)
    sin_lat = np.sin(lat)
    n = WGS84_A_M / np.sqrt(1.0 - _E2 * sin_lat * sin_lat)
    return ((n + h) * np.cos(lat) * np.cos(lon),
            (n + h) * np.cos(lat) * np.sin(lon),
            (n * (1.0 - _E2) + h) * sin_lat)


def ecef_to_geodetic(x: ArrayLike, y: ArrayLike,
                     z: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """WGS84 longitude, latitude (degrees) and height (m) of ECEF X, Y, Z (m).

    Bowring's start and five Newton-free fixed-point steps: < 1e-12 rad for points within a few
    km of the ellipsoid's surface, which is all this module is for.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    z = np.asarray(z, dtype=float)
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1.0 - _E2))
    h = np.zeros_like(p)
    for _ in range(5):
        sin_lat = np.sin(lat)
        n = WGS84_A_M / np.sqrt(1.0 - _E2 * sin_lat * sin_lat)
        # height along the normal; near the poles p/cos(lat) is ill-conditioned, use z instead
        cos_lat = np.cos(lat)
        h = np.where(np.abs(cos_lat) > 1e-3,
                     p / np.where(cos_lat == 0.0, 1.0, cos_lat) - n,
                     z / np.where(sin_lat == 0.0, 1.0, sin_lat) - n * (1.0 - _E2))
        lat = np.arctan2(z, p * (1.0 - _E2 * n / (n + h)))
    return np.degrees(lon), np.degrees(lat), h


@dataclass(frozen=True)
class LocalFrame:
    """The local tangent plane (east, north in metres) at a WGS84 reference point.

    Parameters
    ----------
    lon0_deg, lat0_deg : float
        The reference point (the plane's origin), WGS84 degrees. Not a pole.
    h0_m : float
        Its ellipsoidal height, m; points returned by :meth:`to_wgs84` lie at this height.

    Raises
    ------
    ValueError
        If the reference point is not finite, outside the WGS84 ranges, or a pole.
    """

    lon0_deg: float
    lat0_deg: float
    h0_m: float = 0.0
    _origin: tuple[float, float, float] = field(init=False, repr=False, compare=False)
    _rot: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name, value in (("lon0_deg", self.lon0_deg), ("lat0_deg", self.lat0_deg),
                            ("h0_m", self.h0_m)):
            if not math.isfinite(value):
                raise ValueError(f"{name} must be finite, got {value!r}")
        if not -180.0 <= self.lon0_deg <= 180.0:
            raise ValueError(f"lon0_deg {self.lon0_deg} is outside -180..180")
        if not -89.9 <= self.lat0_deg <= 89.9:
            raise ValueError(f"lat0_deg {self.lat0_deg} is outside -89.9..89.9 "
                             "(east and north are undefined at a pole)")
        lon = math.radians(self.lon0_deg)
        lat = math.radians(self.lat0_deg)
        x, y, z = geodetic_to_ecef(self.lon0_deg, self.lat0_deg, self.h0_m)
        object.__setattr__(self, "_origin", (float(x), float(y), float(z)))
        rot = np.array([
            [-math.sin(lon), math.cos(lon), 0.0],
            [-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat)],
            [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)],
        ])
        object.__setattr__(self, "_rot", rot)

    def _enu(self, lon_deg: ArrayLike, lat_deg: ArrayLike,
             h_m: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x, y, z = geodetic_to_ecef(lon_deg, lat_deg, h_m)
        d = np.stack(np.broadcast_arrays(x - self._origin[0], y - self._origin[1],
                                         z - self._origin[2]))
        enu = np.tensordot(self._rot, d, axes=1)
        return enu[0], enu[1], enu[2]

    def to_local(self, lon_deg: ArrayLike, lat_deg: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """East and north (m) of WGS84 points (degrees; scalars or arrays of one shape)."""
        e, n, _ = self._enu(lon_deg, lat_deg, self.h0_m)
        return e, n

    def to_wgs84(self, east_m: ArrayLike, north_m: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """WGS84 longitude and latitude (degrees) of plane points (m), at the frame's height."""
        e, n = np.broadcast_arrays(np.asarray(east_m, dtype=float),
                                   np.asarray(north_m, dtype=float))
        u = np.zeros_like(e)
        lon = lat = e
        for _ in range(3):
            d = np.tensordot(self._rot.T, np.stack([e, n, u]), axes=1)
            lon, lat, h = ecef_to_geodetic(d[0] + self._origin[0], d[1] + self._origin[1],
                                           d[2] + self._origin[2])
            u = u - (h - self.h0_m)
        return lon, lat

    @classmethod
    def centred_on(cls, lon_deg: ArrayLike, lat_deg: ArrayLike) -> LocalFrame:
        """The frame at the middle of a set of points' bounding box (a field's own frame)."""
        lon = np.asarray(lon_deg, dtype=float)
        lat = np.asarray(lat_deg, dtype=float)
        if lon.size == 0:
            raise ValueError("no points to centre a frame on")
        return cls(float((lon.min() + lon.max()) / 2.0), float((lat.min() + lat.max()) / 2.0))
