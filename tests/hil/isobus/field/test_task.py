"""FieldTask: the set-points and section commands a TC sends, and what it is told back."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import shapely
from shapely.geometry import box, mapping

from hil.isobus.field import (
    Boom,
    FieldPath,
    FieldTask,
    Leg,
    LocalFrame,
    dead_reckoning,
    prescription_from_geojson,
)
from hil.isobus.field.path import Field

FRAME = LocalFrame(116.3, 40.0)


def _map(frame: LocalFrame = FRAME) -> Any:
    def ll(g: Any) -> Any:
        return mapping(shapely.transform(
            g, lambda c: np.column_stack(frame.to_wgs84(c[:, 0], c[:, 1]))))
    feats = [{"type": "Feature", "properties": {"r": r}, "geometry": ll(g)}
             for g, r in ((box(-10, 0, 10, 50), 160.0), (box(-10, 50, 10, 100), 240.0))]
    return prescription_from_geojson({"type": "FeatureCollection", "features": feats,
                                      "prescription": {"rate_property": "r", "unit": "kg/ha",
                                                       "default_rate": 0}}, frame=frame)


def _field() -> Field:
    path = FieldPath([Leg("pass", np.array([[0.0, 0.0], [0.0, 100.0]]), 2.0, 2.0)])
    return Field(FRAME, box(-10, 0, 10, 100), box(-10, 10, 10, 90), path)


def _rate_change_time(task: FieldTask) -> float:
    for t in np.arange(0.0, 50.0, 0.01):
        if task.command(float(t)).rates[0] == 240.0:
            return float(t)
    raise AssertionError("the rate never changed")


@pytest.mark.parametrize("lookahead", [0.0, 0.43, 1.0])
def test_the_rate_set_point_changes_its_latency_before_the_boundary(lookahead: float) -> None:
    boom = Boom.uniform(4, 3.0, fore_aft_m=-1.0)
    task = FieldTask(_field(), _map(), boom, rate_lookahead_s=lookahead)
    # the sections (1 m behind the antenna, at 2 m/s) reach y = 50 m at 25.5 s
    assert _rate_change_time(task) == pytest.approx(25.5 - lookahead, abs=0.011)


def test_commands_carry_ddi_values_and_section_states() -> None:
    task = FieldTask(_field(), _map(), Boom.uniform(4, 3.0))
    cmd = task.command(20.0)                       # antenna at 40 m, inside the work area
    assert cmd.rates.tolist() == [160.0] * 4 and cmd.rates_ddi.tolist() == [16_000] * 4
    assert cmd.sections_on == (True,) * 4 and cmd.pose.north_m == pytest.approx(40.0)
    task.report(cmd.pose, cmd.sections_on, cmd.rates)
    task.report(task.command(20.1).pose, cmd.sections_on, cmd.rates)
    assert task.control.coverage.geometry().area == pytest.approx(3.0 * 0.2)
    assert len(task.as_applied) == 2


def test_a_tc_without_the_path_predicts_from_its_last_fix() -> None:
    fld = _field()
    fix = fld.path.pose(0.0)
    boom = Boom.uniform(4, 3.0, turn_on_s=1.0)
    task = FieldTask(fld, _map(), boom, pose_at=dead_reckoning(fix, 2.0, 0.0))
    on = next(t for t in np.arange(0.0, 10.0, 0.01) if any(task.command(float(t)).sections_on))
    assert on == pytest.approx(5.0 - 1.0 - 0.025, abs=0.011)   # 10 m at 2 m/s, 1 s early


def test_map_and_field_must_share_a_frame() -> None:
    with pytest.raises(ValueError, match="share one frame"):
        FieldTask(_field(), _map(LocalFrame(116.0, 40.0)), Boom.uniform(4, 3.0))
