from __future__ import annotations

import struct
import threading
import time
from pathlib import Path
from typing import ClassVar

import can
import canopen
import pytest

from hil.dut import Controller, InProcessDut
from hil.rig import Rig, RigContext, RunOptions, Scenario, run_scenario
from hil.rig.canopen_device import CanopenDevice
from hil.softbus import SoftwareBus

EDS = Path(__file__).parent / "data" / "io_module.eds"
NODE = 5


def _sync() -> can.Message:
    return can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)


def test_boot_heartbeat_tpdo_on_sync_and_rpdo_store() -> None:
    dev = CanopenDevice("io", NODE, EDS)
    assert dev.next_due(-1.0) == 0.0
    boot = dev.emit(0.0)
    assert [(m.arbitration_id, bytes(m.data)) for m in boot] == [(0x705, b"\x00")]
    assert dev.operational
    assert dev.next_due(0.0) == pytest.approx(0.5)       # 0x1017 = 500 ms
    assert [bytes(m.data) for m in dev.emit(0.5)] == [b"\x05"]
    dev.write(0x6401, 1, -1234)
    tpdo = dev.on_frame(_sync(), 0.6)
    assert [(m.arbitration_id, struct.unpack("<h", bytes(m.data))[0]) for m in tpdo] == [
        (0x185, -1234)]
    rpdo = can.Message(arbitration_id=0x205, data=struct.pack("<hh", 7000, -5),
                       is_extended_id=False)
    assert dev.accepts(rpdo)
    dev.on_frame(rpdo, 0.7)
    assert (dev.read(0x6411, 1), dev.read(0x6411, 2)) == (7000, -5)


def test_nmt_stop_silences_pdos_and_start_resumes() -> None:
    dev = CanopenDevice("io", NODE, EDS)
    dev.emit(0.0)
    dev.on_frame(can.Message(arbitration_id=0, data=bytes([0x02, NODE]), is_extended_id=False),
                 0.1)
    assert dev.node.nmt.state == "STOPPED"
    assert dev.on_frame(_sync(), 0.2) == []
    assert [bytes(m.data) for m in dev.emit(0.5)] == [b"\x04"]
    dev.on_frame(can.Message(arbitration_id=0, data=bytes([0x01, 0]), is_extended_id=False), 0.6)
    assert dev.operational and len(dev.on_frame(_sync(), 0.7)) == 1


def test_silent_device_sends_nothing() -> None:
    dev = CanopenDevice("io", NODE, EDS)
    dev.emit(0.0)
    dev.silent = True
    assert dev.emit(0.5) == [] and dev.on_frame(_sync(), 0.6) == []


class _IoRig(Rig):
    name = "io"
    inputs: ClassVar[dict[str, str]] = {}
    faults: ClassVar[dict[str, str]] = {}

    def __init__(self, ctx: RigContext) -> None:
        super().__init__(ctx)
        self.io = CanopenDevice("io", NODE, EDS)
        self.devices = [self.io]

    def advance(self, n: int, dt: float) -> None:
        return None

    def set_input(self, name: str, value: float, time_s: float) -> None:
        return None

    def set_fault(self, name: str, active: bool, target: int | None, time_s: float) -> None:
        return None

    def command_ids(self) -> frozenset[int]:
        return frozenset()

    def trace_signals(self) -> dict[str, tuple[float, str]]:
        return {"out1": (float(self.io.read(0x6411, 1)), "1")}


class _Idle(Controller):
    def on_frame(self, msg: can.Message) -> list[can.Message]:
        return []


@pytest.mark.realtime
def test_a_canopen_master_reads_and_writes_the_emulated_module_over_the_bus(tmp_path) -> None:
    with SoftwareBus(port=0) as softbus:
        scenario = Scenario(name="io", description="", rig="io", duration_s=3.0)
        result: dict = {}
        runner = threading.Thread(target=lambda: result.update(run=run_scenario(
            _IoRig, scenario, InProcessDut(_Idle()),
            RunOptions(out_dir=tmp_path, clock="realtime", bus=softbus.spec()))))
        network = canopen.Network()
        network.connect(interface="socketcand", host=softbus.host, port=softbus.port,
                        channel="can0", tcp_tune=True)
        try:
            runner.start()
            node = network.add_node(NODE, str(EDS))
            time.sleep(0.3)
            assert node.sdo[0x1000].raw == 0x000F0191
            node.sdo[0x6411][1].raw = 4321
            assert node.sdo[0x6411][1].raw == 4321
            node.sdo[0x1017].raw = 100
            node.tpdo.read()
            assert node.tpdo[1].cob_id == 0x185
            heartbeats = []
            network.subscribe(0x705, lambda cid, data, ts: heartbeats.append(ts))
            time.sleep(0.5)
            assert len(heartbeats) >= 3      # the new 100 ms period took effect
        finally:
            runner.join(10)
            network.disconnect()
    arrays_last = result["run"].record
    assert arrays_last["error"] is None
    from hil.record import load_traces
    assert load_traces(tmp_path / "traces.npz")[0]["out1"][-1] == 4321
