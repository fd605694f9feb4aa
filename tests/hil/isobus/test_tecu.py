"""The tractor ECU: ISO 11783-7 speed messages from the scenario's truth, every 100 ms."""

from __future__ import annotations

from pathlib import Path

import cantools
import pytest

import plant_emulators
from hil.errors import FrameError
from hil.isobus.can_id import decode_id
from hil.isobus.network import IsobusNetwork
from hil.isobus.tecu import (
    DBC_PATH,
    Direction,
    SpeedSource,
    TractorState,
    add_tecu,
    iso11783_7_database,
)
from hil.isobus.wire import ScriptedNode, VirtualWire

FERTILIZER_DBC = Path(plant_emulators.__file__).parent / "fertilizer" / "db" / "fertilizer.dbc"


def run(truth, until: float = 1.0):
    net = IsobusNetwork()
    tecu = add_tecu(net, truth)
    implement = ScriptedNode()
    wire = VirtualWire([net, implement])
    wire.run_until(until)
    return tecu, implement


def decoded(implement: ScriptedNode, pgn: int) -> list[tuple[float, dict]]:
    db = iso11783_7_database()
    out = []
    for t, m in implement.heard:
        fid = decode_id(m.arbitration_id)
        if fid.pgn == pgn:
            frame_id = (m.arbitration_id & ~0xFF) | 0x80       # the DBC's nominal address
            out.append((t, db.decode_message(frame_id, bytes(m.data))))
    return out


def test_three_messages_every_100_ms_at_priority_3_after_the_claim() -> None:
    _tecu, implement = run(lambda t: TractorState(ground_speed_mps=2.0))
    ids = [(round(t, 6), m.arbitration_id) for t, m in implement.heard]
    assert ids[0] == (0.0, 0x18EEFF80)
    speed = [(t, i) for t, i in ids if i != 0x18EEFF80]
    assert [i for _, i in speed[:3]] == [0x0CFE4880, 0x0CFE4980, 0x0CF02280]
    times = sorted({t for t, _ in speed})
    assert times == [round(0.25 + 0.1 * k, 6) for k in range(8)]
    assert all(len(m.data) == 8 for _, m in implement.heard)


def test_wheel_based_over_reads_by_the_slip_ground_based_does_not() -> None:
    state = TractorState(ground_speed_mps=2.0, wheel_slip=0.2,
                         speed_source=SpeedSource.WHEEL_BASED)
    _tecu, implement = run(lambda t: state, until=1.3)
    wheel = decoded(implement, 0xFE48)
    ground = decoded(implement, 0xFE49)
    selected = decoded(implement, 0xF022)
    assert wheel[-1][1]["WheelBasedMachineSpeed"] == pytest.approx(2.5, abs=0.001)
    assert ground[-1][1]["GroundBasedMachineSpeed"] == pytest.approx(2.0, abs=0.001)
    assert selected[-1][1]["MachineSelectedSpeed"] == pytest.approx(2.5, abs=0.001)
    assert selected[-1][1]["SpeedSource"] == "WheelBased"
    # distances: integrated from the first message (t = 0.25 s) on, 1.0 s later
    assert wheel[-1][1]["WheelBasedMachineDistance"] == pytest.approx(2.5, abs=0.002)
    assert ground[-1][1]["GroundBasedMachineDistance"] == pytest.approx(2.0, abs=0.002)
    assert selected[-1][1]["MachineSelectedSpeedDistance"] == pytest.approx(2.5, abs=0.002)


def test_states_from_the_scenario_reach_the_bits() -> None:
    def truth(t: float) -> TractorState:
        late = t > 0.5
        return TractorState(ground_speed_mps=1.0, direction=Direction.REVERSE if late
                            else Direction.FORWARD, key_switch_on=not late,
                            implement_start=late, speed_source=SpeedSource.GROUND_BASED)
    _tecu, implement = run(truth)
    wheel = decoded(implement, 0xFE48)
    first, last = wheel[0][1], wheel[-1][1]
    assert (first["MachineDirection"], first["KeySwitchState"], first["ImplementStartStop"]) == (
        "Forward", "NotOff", "Stop")
    assert (last["MachineDirection"], last["KeySwitchState"], last["ImplementStartStop"]) == (
        "Reverse", "Off", "Start")
    ground = [m for _, m in implement.heard if decode_id(m.arbitration_id).pgn == 0xFE49]
    assert ground[0].data[6] == 0xFF and ground[0].data[7] >> 2 == 0x3F   # reserved: ones
    assert decoded(implement, 0xF022)[0][1]["SpeedSource"] == "GroundBased"


def test_no_implement_state_is_not_available() -> None:
    _tecu, implement = run(lambda t: TractorState(ground_speed_mps=0.0))
    assert decoded(implement, 0xFE48)[0][1]["ImplementStartStop"] == "NotAvailable"


@pytest.mark.parametrize(("state", "match"), [
    (TractorState(ground_speed_mps=-1.0), "ground_speed_mps"),
    (TractorState(ground_speed_mps=1.0, wheel_slip=1.0), "wheel_slip"),
])
def test_a_state_the_messages_cannot_carry_is_refused(state: TractorState, match: str) -> None:
    with pytest.raises(FrameError, match=match):
        run(lambda t: state)


def test_layouts_match_the_fertilizer_rigs_messages() -> None:
    ours = cantools.database.load_file(DBC_PATH)
    theirs = cantools.database.load_file(FERTILIZER_DBC)
    for name in ("WheelBasedSpeedDist", "GroundBasedSpeedDist"):
        mine, other = ours.get_message_by_name(name), theirs.get_message_by_name(name)
        assert (mine.frame_id & 0x3FFFF00) == (other.frame_id & 0x3FFFF00)   # priority, PGN
        for sig in other.signals:
            m = mine.get_signal_by_name(sig.name)
            assert (m.start, m.length, m.scale, m.offset, m.byte_order, m.is_signed) == (
                sig.start, sig.length, sig.scale, sig.offset, sig.byte_order, sig.is_signed)
