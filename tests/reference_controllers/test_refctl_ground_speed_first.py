"""The reference's field rate uses the tractor's ground-based speed (PGN 65097) while it hears
one, whatever the terminal's SpeedSource names (``ground_speed_first_s``; issue #29): in the
terminal build, behind a foreign database (the RC-400), never in the ISOBUS mode (which always
prefers 65097 by its own parameters). The C builds are held to the same rule by their unit
test (firmware/tests/test_fertilizer_adapter.c) and by the RC-400 vectors."""

from __future__ import annotations

from typing import Any

import can
import pytest

from hil.contract.binding import load_binding
from hil.contract.codec import ContractCodec
from hil.contract.registry import rig_contract
from plant_emulators.fertilizer.frames import FertilizerDatabase
from plant_emulators.fertilizer.ground_speed import MachineDirection, TractorSpeedReport
from reference_controllers.fertilizer.adapter import FlowController
from reference_controllers.fertilizer.dbc_adapter import (
    RC400_DATABASE,
    RC400_SIGNALS,
    DbcFlowController,
)
from reference_controllers.fertilizer.isobus_mode import IsobusFlowController
from reference_controllers.fertilizer.speeds import GroundSpeedFirst
from reference_controllers.params import ParamError
from tests.reference_controllers.test_refctl_foreign_db import BINDING, RC400_RIG

DB = FertilizerDatabase()
SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
Q_PER_MPS = 0.1 * 200.0 * 3.0 / 4       # g/s per row per m/s: 200 kg/hm², 3 m, 4 rows
WHEEL, RADAR = 1.5, 1.45                 # the Hall wheel reads 3.4 % fast


def _radar(mps: float) -> can.Message:
    return DB.ground_based_speed(TractorSpeedReport(mps, 0.0, MachineDirection.FORWARD))


def _radar_not_available() -> can.Message:
    msg = _radar(1.0)
    return can.Message(arbitration_id=msg.arbitration_id, is_extended_id=True,
                       data=b"\xff\xff" + bytes(msg.data[2:]))


def _hall(mps: float) -> can.Message:
    return DB.encode("GroundWheelSpeed", {"WheelSpeed": mps, "PulseCount": 0,
                                          "PulsePeriod": 0.01, "Counter": 0, "Moving": 1})


@pytest.mark.parametrize("first_s", [0.3, 0.0])
def test_the_terminal_build_prefers_a_fresh_ground_based_speed(first_s: float) -> None:
    ctl = FlowController("physical", ground_speed_first_s=first_s)
    ctl.on_frame(DB.setpoint(mode=0, enable=True, target_rate_kg_per_hm2=200.0,
                             working_width_m=3.0, speed_source=0, active_rows=4))
    ctl.on_frame(_hall(WHEEL))
    ctl.on_frame(_radar(RADAR))
    preferred = RADAR if first_s else WHEEL
    assert ctl.target_gps() == pytest.approx(Q_PER_MPS * preferred, rel=1e-3)
    for _ in range(3):                   # 0.3 s later: still fresh
        ctl.on_frame(SYNC)
    assert ctl.target_gps() == pytest.approx(Q_PER_MPS * preferred, rel=1e-3)
    ctl.on_frame(SYNC)                   # 0.4 s: the terminal's source again
    assert ctl.target_gps() == pytest.approx(Q_PER_MPS * WHEEL, rel=1e-3)
    ctl.on_frame(_radar(RADAR))
    assert ctl.target_gps() == pytest.approx(Q_PER_MPS * preferred, rel=1e-3)
    ctl.on_frame(_radar_not_available())  # "not available" is no speed to prefer
    assert ctl.target_gps() == pytest.approx(Q_PER_MPS * WHEEL, rel=1e-3)


def test_no_source_stays_no_speed_and_bad_values_are_refused() -> None:
    first = GroundSpeedFirst(0.3, 0.1)
    first.heard(1.4, step=0)
    speeds = {"hall": 1.5, "wheel": 1.6, "ground": 1.4}
    assert first.field_speed(speeds, None, 0) == 0.0       # the terminal asked for none
    assert first.field_speed(speeds, "wheel", 3) == 1.4
    assert first.field_speed(speeds, "wheel", 4) == 1.6
    with pytest.raises(ParamError, match="ground_speed_first_s must be >= 0"):
        FlowController("physical", ground_speed_first_s=-1)


def _rc400_frames(values: dict[str, Any]) -> list[can.Message]:
    codec = ContractCodec(rig_contract("fertilizer", RC400_RIG), load_binding(BINDING))
    return codec.encode(values, strict=False)


def test_the_rc400_build_prefers_its_radar_too() -> None:
    ctl = DbcFlowController(RC400_DATABASE, RC400_SIGNALS, {"mode": "physical"})
    for values in ({"target_rate": 200.0, "working_width": 3.0, "target_flow": 0.0,
                    "mode": 0, "enable": 1, "speed_source": 0, "active_rows": 4,
                    "setpoint_counter": 1},
                   {"wheel_speed": WHEEL}, {"ground_based_speed": RADAR}):
        for msg in _rc400_frames(values):
            ctl.on_frame(msg)
    assert ctl.target_gps() == pytest.approx(Q_PER_MPS * RADAR, rel=1e-3)
    for _ in range(4):
        ctl.on_frame(SYNC)
    assert ctl.target_gps() == pytest.approx(Q_PER_MPS * WHEEL, rel=1e-2)


def test_the_isobus_mode_refuses_the_terminal_parameter() -> None:
    with pytest.raises(ParamError, match=r"ground_speed_first_s.*ISOBUS mode"):
        IsobusFlowController("physical", ground_speed_first_s=0.3)
