"""Analog output module EDS: loads in canopen, agrees with the DBC and the rig wiring."""

from __future__ import annotations

import canopen
import pytest

from plant_emulators.fertilizer.frames import FertilizerDatabase


@pytest.fixture(scope="module")
def eds(rig_config) -> str:
    return rig_config.wiring.analog_output_eds_file


@pytest.fixture(scope="module")
def node_id(rig_config) -> int:
    return rig_config.wiring.analog_output_node_id


def test_loads_as_local_and_remote_node(eds, node_id):
    local = canopen.LocalNode(node_id, eds)
    remote = canopen.RemoteNode(node_id, eds)
    for node in (local, remote):
        od = node.object_dictionary
        assert od[0x1000].default == 0x00080191          # CiA 401, analog outputs
        assert od[0x1018][2].default == 0x3402
        assert od[0x1014].default == 0x80 + node_id


def test_rpdo1_maps_both_channels_at_the_dbc_id(eds, node_id):
    od = canopen.LocalNode(node_id, eds).object_dictionary
    db = FertilizerDatabase()
    assert od[0x1400][1].default == 0x200 + node_id == db.frame_id("AnalogOutputCommand")
    assert od[0x1400][2].default == 255
    assert od[0x1600][0].default == 2
    assert od[0x1600][1].default == 0x64110110
    assert od[0x1600][2].default == 0x64110210
    assert od[0x6411][1].pdo_mappable and od[0x6411][2].pdo_mappable


def test_dbc_frame_decodes_identically_through_the_eds_mapping(eds, node_id):
    node = canopen.LocalNode(node_id, eds)
    canopen.Network().add_node(node)     # unconnected: only lets the PDO subscribe
    node.rpdo.read(from_od=True)
    rpdo = node.rpdo[1]
    msg = FertilizerDatabase().analog_output_command(ch1_mv=7321, ch2_mv=12)
    rpdo.on_message(msg.arbitration_id, bytes(msg.data), 0.0)
    assert rpdo[0].raw == 7321
    assert rpdo[1].raw == 12


def test_scaling_and_error_value_match_the_rig_config(eds, node_id, rig_config):
    od = canopen.LocalNode(node_id, eds).object_dictionary
    assert od[0x6411][1].min == 0
    assert od[0x6411][1].max == rig_config.analog_output.full_scale_mv
    assert od[0x6443][1].default == 1
    assert od[0x6444][1].default == rig_config.analog_output.error_value_mv


def test_heartbeats_match_the_wiring(eds, node_id, rig_config):
    od = canopen.LocalNode(node_id, eds).object_dictionary
    assert od[0x1017].default == rig_config.wiring.analog_output_heartbeat_ms
    consumer = od[0x1016][1].default
    assert consumer >> 16 == rig_config.wiring.dut_node_id
    assert 0 < consumer & 0xFFFF <= 1000
    db = FertilizerDatabase()
    assert db.message("AnalogOutputHeartbeat").cycle_time == od[0x1017].default


def test_sdo_round_trip_between_remote_and_local(eds, node_id):
    network_local = canopen.Network()
    network_remote = canopen.Network()
    network_local.connect(interface="virtual", channel="eds-test", receive_own_messages=False)
    network_remote.connect(interface="virtual", channel="eds-test")
    try:
        local = canopen.LocalNode(node_id, eds)
        network_local.add_node(local)
        remote = network_remote.add_node(node_id, eds)
        remote.sdo[0x6411][1].raw = 5000
        assert local.sdo[0x6411][1].raw == 5000
        assert remote.sdo[0x1018][2].raw == 0x3402
    finally:
        network_local.disconnect()
        network_remote.disconnect()
