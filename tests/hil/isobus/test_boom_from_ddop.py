"""The boom the TC reads from an implement's DDOP: a sectionless implement's working width is
placed where its element's offsets say, as a section's is (a seed line 1.9 m behind the
connector used to be placed at the connector: the TC then sent each zone's depth 1.9 m early)."""

from __future__ import annotations

from hil.isobus.tractor import boom_from_ddop
from reference_controllers.sowing_depth.isobus_mode import IsobusDepthParams, depth_pool


def test_a_sectionless_implements_width_sits_at_its_elements_offsets() -> None:
    pool, _ = depth_pool(name=0x1234, width_m=2.4, offset_x_mm=-1900, params=IsobusDepthParams())
    boom, sections = boom_from_ddop(pool)
    assert sections == []
    (section,) = boom.sections
    assert (section.width_m, section.lateral_m, section.fore_aft_m) == (2.4, 0.0, -1.9)
