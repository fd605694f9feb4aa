"""The depth rig as an ISOBUS tractor: a [tractor] scenario drives it along the path."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hil.errors import ConfigError
from hil.rig import RigContext
from plant_emulators.sowing_depth.rig import SowingDepthRig


def _rig(scenario) -> SowingDepthRig:
    return SowingDepthRig(RigContext(seed=1, rng=np.random.default_rng(1), scenario=scenario))


def test_a_field_run_replaces_the_terminal_with_the_tractor_and_follows_the_path() -> None:
    scenario = SowingDepthRig.load_scenario("isobus-depth-field")
    rig = _rig(scenario)
    try:
        run = rig.field_run
        assert run is not None
        assert rig.terminal not in rig.devices and run.device in rig.devices
        names = [name for name, _ in rig._TRACE_LAYOUT]
        assert names[-4:] == ["seed_east_m", "seed_north_m", "heading_deg", "on_pass"]
        # standing for drive_after_s, then at the path's speed (the GNSS line reports it)
        rig.advance(10, 0.001)
        assert rig.plant.ground_speed_mps == 0.0
        for _ in range(1500):                  # to 15 s: on the first pass at 6 km/h
            rig.advance(10, 0.001)
        pose = run.pose(rig.plant.time_s - 0.01)
        assert rig.plant.ground_speed_mps == pytest.approx(pose.speed_m_s)
        assert pose.speed_m_s == pytest.approx(6 / 3.6, rel=0.01)
        row = rig.trace_row()
        assert row[0] in (30.0, 35.0, 40.0)     # the map's depth under the seed line
        east, north = run.seed_point(pose)
        assert np.hypot(east - pose.east_m, north - pose.north_m) == pytest.approx(1.9)
        assert "field_run" in rig.truth()
    finally:
        rig.close()


def test_a_rate_map_is_refused_on_the_depth_rig() -> None:
    scenario = SowingDepthRig.load_scenario("isobus-depth-field")
    rates = scenario.tractor.field.replace("field-rect.geojson", "rates-3zones.geojson")
    bad = dataclasses.replace(scenario, tractor=dataclasses.replace(scenario.tractor,
                                                                    prescription=rates))
    with pytest.raises(ConfigError, match="seeding-depth map"):
        _rig(bad)


def test_a_scenario_asking_for_the_vt_is_refused_on_the_depth_rig() -> None:
    """The depth rig's field run has no VT: a scenario with one is refused, not run without it
    (its operator's steps would judge nothing)."""
    scenario = SowingDepthRig.load_scenario("isobus-depth-field")
    bad = dataclasses.replace(scenario, tractor=dataclasses.replace(scenario.tractor, vt=True))
    with pytest.raises(ConfigError, match="no Virtual Terminal"):
        _rig(bad)
