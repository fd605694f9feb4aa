"""The sowing-depth rig's fast paths leave every value as it was.

* ``trace_row()`` gives the values of the dict ``trace_signals()`` always built, in its order;
* the CANopen node packs TPDOs and unpacks RPDOs of whole-byte mappings itself (canopen's own
  byte-aligned branch): same frames, same object dictionary, same drive state as canopen's
  per-variable path;
* the drive re-derives its parameters only when one of the objects they come from is written.
"""

from __future__ import annotations

import math

import can
import numpy as np
import pytest

from hil.rig import RigContext
from hil.rig.canopen_device import CanopenDevice
from plant_emulators.sowing_depth.cia402 import _PARAMETER_KEYS, OBJECTS
from plant_emulators.sowing_depth.rig import SowingDepthRig
from plant_emulators.sowing_depth.sensors import calibration_depth_mm


def _old_trace_signals(rig: SowingDepthRig) -> dict[str, tuple[float, str]]:
    p = rig.plant
    drive = p.drive
    return {
        "target_depth_mm": (rig.terminal.target_depth_mm, "mm"),
        "mean_true_depth_mm": (p.mean_true_depth_mm, "mm"),
        "sensed_depth_mm": (calibration_depth_mm(rig.incl_device.last_x_mv)
                            if rig.incl_device.last_x_mv else float("nan"), "mm"),
        "rod_position_mm": (p.rod_position_mm, "mm"),
        "rod_velocity_mm_s": (p.rod_velocity_mm_s, "mm/s"),
        "rod_force_n": (p.rod_force_n, "N"),
        "motor_current_a": (p.motor_current_a, "A"),
        "cover_soil_mm": (p.cover_soil_mm, "mm"),
        "arm_angle_deg": (p.arm_angle_deg, "deg"),
        "machine_pitch_deg": (p.machine_pitch_deg, "deg"),
        "ground_speed_mps": (p.ground_speed_mps, "m/s"),
        "distance_m": (p.distance_m, "m"),
        "drive_statusword": (float(drive.statusword), "1"),
        "drive_error_code": (float(drive.error_code), "1"),
    }


def _same(a: float, b: float) -> bool:
    return type(a) is type(b) and (a == b or (math.isnan(a) and math.isnan(b)))


@pytest.fixture
def rig():
    rig = SowingDepthRig(RigContext(seed=3, rng=np.random.default_rng(3)))
    yield rig
    rig.close()


def test_trace_row_is_the_old_dict_in_order(rig: SowingDepthRig) -> None:
    rig.set_input("ground_speed_mps", 1.2, 0.0)
    for step in range(300):
        rig.advance(10, 0.001)
        if step % 7 == 0:
            rig.incl_device.emit(step * 0.01)
        old = _old_trace_signals(rig)
        new = rig.trace_signals()
        assert list(new) == list(old)
        assert all(_same(a, b) for a, (b, _) in zip(rig.trace_row(), old.values(), strict=True))
        assert all(_same(a, b) and u == v for (a, u), (b, v) in
                   zip(new.values(), old.values(), strict=True))


def _operational(rig: SowingDepthRig) -> None:
    drive = rig.drive
    drive.emit(0.0)                                         # boot-up
    drive.on_frame(can.Message(arbitration_id=0x000, is_extended_id=False,
                               data=bytes([0x01, drive.node_id])), 0.0)   # NMT start
    assert drive.operational


def test_tpdos_and_rpdos_match_canopens_per_variable_path(monkeypatch) -> None:
    rigs = [SowingDepthRig(RigContext(seed=8, rng=np.random.default_rng(8))) for _ in range(2)]
    fast, slow = rigs
    monkeypatch.setattr(slow.drive, "_byte_plan", lambda pdo: None)   # canopen's own path
    try:
        rng = np.random.default_rng(1)
        for r in rigs:
            _operational(r)
            r.set_input("ground_speed_mps", 1.0, 0.0)
        assert all(fast.drive._byte_plan(t) is not None for t in fast.drive._tpdos)
        node = fast.drive.node_id
        for k in range(200):
            controlword = [0x06, 0x07, 0x0F, 0x0F, 0x0F][min(k, 4)]
            rpdo = can.Message(arbitration_id=0x300 + node, is_extended_id=False,
                               data=controlword.to_bytes(2, "little")
                               + int(rng.integers(-3000, 3000)).to_bytes(4, "little",
                                                                          signed=True))
            mode = can.Message(arbitration_id=0x400 + node, is_extended_id=False,
                               data=bytes([3]))
            sync = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
            out = []
            for r in rigs:
                frames = []
                for msg in ([mode] if k == 0 else []) + [rpdo, sync]:
                    frames += r.drive.on_frame(msg, k * 0.01)
                r.advance(10, 0.001)
                out.append([(m.arbitration_id, bytes(m.data)) for m in frames])
            assert out[0] == out[1]
            assert len(out[0]) >= 3                           # the SYNC TPDOs
        assert fast.drive.node.data_store == slow.drive.node.data_store
        assert fast.drive.rejected == slow.drive.rejected
        assert fast.plant.drive.statusword == slow.plant.drive.statusword
        assert fast.plant.rod_position_mm == slow.plant.rod_position_mm
    finally:
        for r in rigs:
            r.close()


def test_a_remapped_pdo_gets_a_new_plan(rig: SowingDepthRig) -> None:
    device: CanopenDevice = rig.drive
    tpdo = device._tpdos[0]
    plan = device._byte_plan(tpdo)
    assert device._byte_plan(tpdo) is plan                  # cached
    device._reload_pdos()                                  # canopen rebuilds the variable list
    again = device._byte_plan(device._tpdos[0])
    assert again is not plan and [v for v in again[0] if v is plan[0][0]] == []
    assert [step[1:] for step in again] == [step[1:] for step in plan]


DERIVED = ("_vmax", "_v_profile", "_accel", "_decel", "_qs_decel", "_fe_window",
           "_fe_timeout_s", "_pos_window", "_pos_window_s", "_vel_window", "_vel_window_s",
           "_vel_threshold", "_vel_threshold_s", "_lim_min", "_lim_max", "_overload_limit_s")


def test_only_the_parameter_objects_feed_the_derived_parameters(rig: SowingDepthRig) -> None:
    drive = rig.plant.drive

    def derived():
        return [getattr(drive, name) for name in DERIVED] + [drive.cylinder.torque_limit_n_m]

    for key, spec in OBJECTS.items():
        if key not in drive._od:
            continue
        before, saved = derived(), drive._od[key]
        drive._od[key] = saved + 7 if saved < 1000 else saved - 7
        drive._apply_parameters()
        changed = derived() != before
        drive._od[key] = saved
        drive._apply_parameters()
        assert changed == (key in _PARAMETER_KEYS), (hex(key[0]), key[1], spec.name)
