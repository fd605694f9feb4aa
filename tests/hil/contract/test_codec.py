"""The codec: the rig's default binding gives the frames the rig's DBC helpers gave, byte for
byte; a foreign database (other ids, big-endian, a multiplexed row message, kg/h, a mapped
enum) carries the same quantities; the fertilizer rig sends the DUT's frames when bound."""

from __future__ import annotations

import math

import can
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.contract.binding import load_binding
from hil.contract.codec import ContractCodec
from hil.contract.quantity import Contract
from hil.errors import FrameError
from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fertilizer.flow_sensor import FlowReport, SensorStatus
from plant_emulators.fertilizer.frames import FertilizerDatabase
from plant_emulators.fertilizer.rig import FertilizerRig
from tests.hil.contract.conftest import ACME_BINDING


@pytest.fixture(scope="module")
def default(fert: Contract) -> ContractCodec:
    return ContractCodec.for_contract(fert)


@pytest.fixture(scope="module")
def foreign(fert: Contract) -> ContractCodec:
    return ContractCodec(fert, load_binding(ACME_BINDING))


def _report(flow: float, mass: float, counter: int, status: int, window: float) -> FlowReport:
    return FlowReport(0.0, mass, flow, counter, SensorStatus(status), window)


@settings(max_examples=150, deadline=None)
@given(row=st.integers(1, 4), flow=st.floats(0, 250), mass=st.floats(0, 250),
       counter=st.integers(0, 255), status=st.integers(0, 15),
       window=st.sampled_from([0.1, 1.0, 2.5]))
def test_default_binding_gives_the_dbc_helpers_frames(default: ContractCodec, row: int,
                                                      flow: float, mass: float, counter: int,
                                                      status: int, window: float) -> None:
    """The rig's devices went from ``FertilizerDatabase.flow_module`` to the codec: same bytes."""
    db = FertilizerDatabase()
    report = _report(flow, mass, counter, status, window)
    expected = db.flow_module(row, report)
    from plant_emulators.fertilizer.devices import FlowModuleDevice

    device = FlowModuleDevice(row, None, default, 250.0)  # type: ignore[arg-type]
    (got,) = device.encode(report)
    assert (got.arbitration_id, got.is_extended_id, got.dlc, bytes(got.data)) == \
        (expected.arbitration_id, expected.is_extended_id, expected.dlc, bytes(expected.data))


def test_default_setpoint_and_speed_frames_are_the_helpers(default: ContractCodec) -> None:
    db = FertilizerDatabase()
    (got,) = default.encode({"target_rate": 200.0, "working_width": 3.0, "target_flow": 23.0,
                             "mode": 0, "enable": 1, "speed_source": 2, "active_rows": 4,
                             "setpoint_counter": 9})
    want = db.setpoint(mode=0, enable=True, target_flow_gps=23.0, target_rate_kg_per_hm2=200.0,
                       working_width_m=3.0, speed_source=2, active_rows=4, counter=9)
    assert bytes(got.data) == bytes(want.data) and got.arbitration_id == want.arbitration_id


@settings(max_examples=150, deadline=None)
@given(rate=st.floats(0, 1000), width=st.floats(0, 30), flow=st.floats(0, 250),
       mode=st.sampled_from([0, 1, 2]), enable=st.integers(0, 1), counter=st.integers(0, 255),
       row=st.integers(1, 4), row_flow=st.floats(0, 250), ready=st.integers(0, 1))
def test_a_foreign_layout_carries_the_same_quantities(default: ContractCodec,
                                                      foreign: ContractCodec, rate: float,
                                                      width: float, flow: float, mode: int,
                                                      enable: int, counter: int, row: int,
                                                      row_flow: float, ready: int) -> None:
    """Encoded in either layout and decoded back, each quantity agrees within the coarser
    carrier's step (the acme flow set-point is 0.02 kg/h = 0.0056 g/s a bit)."""
    setpoint = {"target_rate": rate, "working_width": width, "target_flow": flow,
                "mode": mode, "enable": enable, "setpoint_counter": counter}
    flows = {"row_flow": row_flow, "row_baseline_ready": ready}
    for codec in (default, foreign):
        got = {}
        for frame in codec.encode(setpoint) + codec.encode(flows, row=row):
            got.update(codec.decode(frame) or {})
        assert got["target_rate"] == pytest.approx(rate, abs=0.05 + 1e-9)
        assert got["working_width"] == pytest.approx(width, abs=0.0005 + 1e-9)
        assert got["target_flow"] == pytest.approx(flow, abs=0.02 / 3.6 / 2 + 0.005 + 1e-9)
        assert got["mode"] == mode and got["enable"] == enable
        assert got[f"row_flow[{row}]"] == pytest.approx(row_flow, abs=0.005 + 1e-9)
        assert got[f"row_baseline_ready[{row}]"] == ready


def test_the_foreign_frames_are_the_dut_database_s(foreign: ContractCodec) -> None:
    """Ids, byte order, multiplexer and value map as the acme database says."""
    (setpoint,) = foreign.encode({"target_rate": 200.0, "working_width": 3.0,
                                  "target_flow": 10.0, "mode": 0, "enable": 1,
                                  "setpoint_counter": 17})
    assert setpoint.arbitration_id == 0x310
    data = bytes(setpoint.data)
    assert data[0:2] == (2000).to_bytes(2, "big")              # 200 kg/ha at 0.1, big-endian
    assert data[2:4] == (3000).to_bytes(2, "big")              # 3 m = 3000 mm
    assert data[4:6] == round(10.0 * 3.6 / 0.02).to_bytes(2, "big")   # 36 kg/h at 0.02
    assert data[6] >> 5 == 2 and (data[6] >> 4) & 1 == 1 and data[6] & 0xF == 17 % 16
    (row3,) = foreign.encode({"row_flow": 12.5}, row=3)
    assert row3.arbitration_id == 0x320 and row3.data[0] == 3    # RowIdx 3
    assert int.from_bytes(row3.data[1:3], "little") == round(12.5 / 0.005)


def test_a_value_the_binding_cannot_map_is_a_named_error(foreign: ContractCodec) -> None:
    with pytest.raises(FrameError, match="mode"):
        foreign.encode({"mode": 3})


def test_quantities_the_binding_leaves_out_are_not_sent(foreign: ContractCodec) -> None:
    assert foreign.encode({"wheel_based_speed": 1.0, "wheel_based_distance": 2.0,
                           "wheel_based_direction": 1}) == []
    with pytest.raises(FrameError, match="no quantity 'nonsense'"):
        foreign.encode({"nonsense": 1.0})


def test_the_rig_bound_to_the_dut_database_sends_its_frames(tmp_path) -> None:
    """A FertilizerRig with the acme binding: its devices emit the acme ids, it waits for
    the acme motor command and records the DUT's status by quantity."""
    from hil.rig import RigContext

    overrides = {"wiring": {"binding_file": str(ACME_BINDING)}}
    cfg = load_rig_config(overrides=overrides)
    rig = FertilizerRig(RigContext(seed=1, rng=np.random.default_rng(1),
                                   config_overrides=overrides), cfg)
    rig.set_input("target_flow_gps", 20.0, 0.0)
    ids = set()
    for device in rig.devices:
        if hasattr(device, "frames") and device.name in ("terminal setpoints",
                                                         "tractor ECU speed",
                                                         "ground wheel speed"):
            ids |= {m.arbitration_id for m in device.frames(0.0)}
    assert ids == {0x310, 0x18FF50F0}                   # set-points; ground speed in km/h
    assert rig.command_ids() == frozenset({0x220})
    assert rig.terminal.period_s == pytest.approx(0.1)  # the acme database's 100 ms cycle
    assert not math.isnan(rig.codec.contract.quantity("row_flow").maximum)


def test_an_undecodable_dut_frame_is_a_frame_error(default: ContractCodec) -> None:
    with pytest.raises(FrameError, match="ControllerStatus"):
        default.decode(can.Message(arbitration_id=0x190, is_extended_id=False, data=b"\x01"))


@settings(max_examples=120, deadline=None)
@given(depth=st.floats(0, 150), manual=st.floats(0, 100), enable=st.booleans(),
       is_manual=st.booleans(), counter=st.integers(0, 15), x=st.integers(0, 5000),
       y=st.integers(0, 5000), speed=st.floats(0, 20), distance=st.floats(0, 4e6),
       position=st.floats(0, 150))
def test_the_depth_rig_s_default_binding_gives_its_frame_codec_s_frames(
        depth: float, manual: float, enable: bool, is_manual: bool, counter: int, x: int,
        y: int, speed: float, distance: float, position: float) -> None:
    """The depth devices went from the typed ``FrameCodec`` (choice names) to the codec
    (quantity values): same bytes."""
    from plant_emulators.sowing_depth import frames as f
    from plant_emulators.sowing_depth.config import load_rig_config as depth_config
    from plant_emulators.sowing_depth.rig import SowingDepthRig

    codec = SowingDepthRig.contract_codec(depth_config())
    old = f.FrameCodec()
    pairs = [
        (codec.encode({"target_depth": depth, "manual_roller_position": manual,
                       "depth_enable": int(enable), "depth_mode": 0 if is_manual else 1,
                       "setpoint_counter": counter}),
         old.encode(f.DepthSetpoint(depth, manual, "on" if enable else "off",
                                    "manual" if is_manual else "automatic", counter))),
        (codec.encode({"inclinometer_x": x, "inclinometer_y": y, "inclinometer_x_status": 0,
                       "inclinometer_y_status": 2, "inclinometer_counter": counter}),
         old.encode(f.InclinometerFrame(x, y, "ok", "above range", counter))),
        (codec.encode({"ground_speed": speed, "ground_distance": distance,
                       "ground_direction": 1}),
         old.encode(f.GroundSpeed(speed, distance))),
        (codec.encode({"roller_position": position, "roller_position_status": 0,
                       "roller_position_counter": counter}),
         old.encode(f.DrawWireFrame(position, "ok", counter))),
    ]
    for (got,), want in pairs:
        assert (got.arbitration_id, got.is_extended_id, bytes(got.data)) == \
            (want.arbitration_id, want.is_extended_id, bytes(want.data))
