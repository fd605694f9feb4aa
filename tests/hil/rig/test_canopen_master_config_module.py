"""A master configures the fertilizer rig's C-3402 analog output module (CiA 401) by SDO.

The module as the rig runs it, in lockstep against canopen's ``RemoteNode``
(:class:`~.test_canopen_master_config.Loopback`): a remapped, synchronous RPDO1 on a new COB-ID
drives the output at the next SYNC; the consumer heartbeat watches the node and time the master
set; the error behaviour 0x1029 decides the NMT state on a heartbeat timeout.
"""

from __future__ import annotations

import can
import pytest

from plant_emulators.fertilizer.devices import AnalogOutputModule

from .test_canopen_master_config import Loopback, check_access_and_mapping
from .test_canopen_master_config_refusals import module_loop


def _module(loop: Loopback) -> AnalogOutputModule:
    assert isinstance(loop.device, AnalogOutputModule)
    return loop.device


def _rpdo(can_id: int, first: int, second: int) -> can.Message:
    data = first.to_bytes(2, "little", signed=True) + second.to_bytes(2, "little", signed=True)
    return can.Message(arbitration_id=can_id, data=data, is_extended_id=False)


def test_a_remapped_synchronous_rpdo_drives_the_output_at_the_next_sync() -> None:
    loop = module_loop()
    module, master = _module(loop), loop.master
    master.rpdo.read()
    rpdo = master.rpdo[1]
    rpdo.clear()
    rpdo.add_variable(0x6411, 2)
    rpdo.add_variable(0x6411, 1)                       # the channels swapped
    rpdo.cob_id, rpdo.trans_type = 0x321, 1
    rpdo.save()
    assert module.refused == []
    sub = module.output_sub
    assert not module.accepts(_rpdo(0x220, 7000, 0))  # the old COB-ID is no RPDO now
    loop.to_device(_rpdo(0x321, 1234, 7000))           # 0x6411:02 = 1234, 0x6411:01 = 7000
    assert module.read(0x6411, sub) == 0                # synchronous: not before the SYNC
    master.network.sync.transmit()
    assert (module.read(0x6411, 1), module.read(0x6411, 2)) == (7000, 1234)
    assert module.output_volts() == pytest.approx(module.channel.volts(7000))


def _beat(loop: Loopback, node: int, until: float, period: float = 0.05) -> None:
    t = loop.t
    while t + period <= until + 1e-9:
        t += period
        loop.run_until(t)
        loop.to_device(can.Message(arbitration_id=0x700 + node, data=b"\x05",
                                   is_extended_id=False))


def test_the_consumer_heartbeat_watches_the_node_and_time_the_master_set() -> None:
    loop = module_loop()
    module, master = _module(loop), loop.master
    master.sdo[0x1016][1].raw = 0x00110000 | 200        # node 0x11, 200 ms
    loop.start_sync(0.01)                                # EMCYs go out at the next SYNC
    assert (module.watched_node, module.consumer_time_s) == (0x11, 0.2)
    _beat(loop, 0x10, until=1.0)                         # the old node counts no more
    assert not module.heartbeat_seen
    _beat(loop, 0x11, until=2.0)
    assert module.heartbeat_seen and not module.comm_error
    loop.run_until(2.0 + 0.19)
    assert not module.comm_error
    loop.run_until(2.0 + 0.21)
    assert module.comm_error and [e.code for e in master.emcy.active] == [0x8130]
    master.sdo[0x1016][1].raw = 0                        # monitoring off: the error ends
    loop.run_until(loop.t + 1.0)
    assert not module.comm_error and master.emcy.active == []


@pytest.mark.parametrize(("behaviour", "state"), [(0, 0x7F), (1, 0x05), (2, 0x04)])
def test_error_behaviour_sets_the_nmt_state_on_a_heartbeat_timeout(behaviour: int,
                                                                    state: int) -> None:
    loop = module_loop()
    module, master = _module(loop), loop.master
    master.sdo[0x1029][1].raw = behaviour
    _beat(loop, module.watched_node, until=1.0)
    loop.run_until(3.0)                                  # 2 s of silence: timeout at 1.3 s
    assert module.comm_error
    heartbeats = loop.sent(0x700 + module.node_id)
    assert heartbeats[-1][1].data[0] == state
    assert module.output_volts() == pytest.approx(module.channel.error_volts())


def test_every_module_object_is_writable_and_mappable_as_its_eds_says() -> None:
    loop = module_loop()
    loop.start_sync(0.01)
    loop.run_until(0.1)
    # counted by hand from the EDS: 14 rw, 24 ro (without 0x1600); 0x6411:01/02 map into
    # RPDO1; the module has no TPDO
    assert check_access_and_mapping(loop, rpdo=1, tpdo=None) == {
        "rw": 14, "ro": 24, "rpdo": 2, "tpdo": 0}
