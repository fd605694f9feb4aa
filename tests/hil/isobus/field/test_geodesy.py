"""The local tangent plane against Vincenty's geodesic distance, and its round trips."""

from __future__ import annotations

import doctest
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.isobus.field import geodesy
from hil.isobus.field.geodesy import LocalFrame, ecef_to_geodetic, geodetic_to_ecef
from tests.hil.isobus.field._vincenty import vincenty_m


def _worst_distance_error_m(lat0: float, side_m: float, pairs: int = 60) -> float:
    frame = LocalFrame(10.0, lat0)
    rng = np.random.default_rng(7)
    e = rng.uniform(-side_m / 2, side_m / 2, (pairs, 2))
    n = rng.uniform(-side_m / 2, side_m / 2, (pairs, 2))
    lon, lat = frame.to_wgs84(e, n)
    return max(abs(math.hypot(e[i, 0] - e[i, 1], n[i, 0] - n[i, 1])
                   - vincenty_m(lon[i, 0], lat[i, 0], lon[i, 1], lat[i, 1]))
               for i in range(pairs))


@pytest.mark.parametrize("lat0", [0.0, 45.0, 70.0, -33.0])
def test_plane_distances_match_the_geodesic_in_a_field(lat0: float) -> None:
    # the figures the module's docstring states (2 km: 0.02 mm, 10 km: 1.8 mm)
    assert _worst_distance_error_m(lat0, 2_000.0) < 0.05e-3
    assert _worst_distance_error_m(lat0, 10_000.0) < 2.5e-3


def test_the_reference_would_see_a_flat_earth_error() -> None:
    # the check can fail: an equirectangular plane (no meridian convergence) is 10 cm off
    frame = LocalFrame(10.0, 60.0)
    lon, lat = frame.to_wgs84(np.array([0.0, 1000.0]), np.array([-1000.0, 1000.0]))
    k = math.pi / 180 * 6_378_137.0
    flat = math.hypot((lon[1] - lon[0]) * k * math.cos(math.radians(60.0)),
                      (lat[1] - lat[0]) * k)
    geodesic = vincenty_m(lon[0], lat[0], lon[1], lat[1])
    assert abs(flat - geodesic) > 0.05
    assert abs(math.hypot(1000.0, 2000.0) - geodesic) < 1e-4


def test_ecef_round_trip_and_a_known_point() -> None:
    x, y, z = geodetic_to_ecef(0.0, 0.0, 0.0)
    assert (float(x), float(y), float(z)) == pytest.approx((6_378_137.0, 0.0, 0.0))
    x, y, z = geodetic_to_ecef(0.0, 90.0, 0.0)
    assert float(z) == pytest.approx(6_356_752.314245, abs=1e-6)  # the WGS84 polar radius
    lon, lat, h = ecef_to_geodetic(*geodetic_to_ecef(-71.3, 89.95, 120.0))
    assert (float(lon), float(lat), float(h)) == pytest.approx((-71.3, 89.95, 120.0), abs=1e-6)


@settings(max_examples=200, deadline=None)
@given(lon0=st.floats(-179.0, 179.0), lat0=st.floats(-85.0, 85.0),
       e=st.floats(-5_000.0, 5_000.0), n=st.floats(-5_000.0, 5_000.0))
def test_plane_to_wgs84_and_back(lon0: float, lat0: float, e: float, n: float) -> None:
    frame = LocalFrame(lon0, lat0)
    lon, lat = frame.to_wgs84(e, n)
    e2, n2 = frame.to_local(lon, lat)
    assert float(e2) == pytest.approx(e, abs=1e-6)
    assert float(n2) == pytest.approx(n, abs=1e-6)


@settings(max_examples=200, deadline=None)
@given(lon0=st.floats(-179.0, 179.0), lat0=st.floats(-85.0, 85.0),
       dlon=st.floats(-0.05, 0.05), dlat=st.floats(-0.05, 0.05))
def test_wgs84_to_plane_and_back(lon0: float, lat0: float, dlon: float, dlat: float) -> None:
    frame = LocalFrame(lon0, lat0)
    lon, lat = frame.to_wgs84(*frame.to_local(lon0 + dlon, lat0 + dlat))
    assert float(lat) == pytest.approx(lat0 + dlat, abs=1e-9)
    wrapped = (float(lon) - (lon0 + dlon) + 180.0) % 360.0 - 180.0
    assert wrapped == pytest.approx(0.0, abs=1e-9)


def test_axes_point_east_and_north() -> None:
    frame = LocalFrame(116.3, 40.0)
    e, n = frame.to_local([116.31, 116.3], [40.0, 40.01])
    assert e[0] > 800 and abs(n[0]) < 1.0
    assert n[1] > 1100 and abs(e[1]) < 1e-6


@pytest.mark.parametrize(("lon", "lat", "words"), [(0.0, 90.0, "pole"), (200.0, 0.0, "lon0"),
                                                   (float("nan"), 0.0, "finite")])
def test_bad_reference_points_are_refused(lon: float, lat: float, words: str) -> None:
    with pytest.raises(ValueError, match=words):
        LocalFrame(lon, lat)


def test_docstring_example() -> None:
    assert doctest.testmod(geodesy).failed == 0
