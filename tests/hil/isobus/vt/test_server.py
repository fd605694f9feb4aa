"""The VT server through the real network layer against a VT client, in virtual time."""

from __future__ import annotations

import pytest

from hil.isobus.vt.bench import IMPLEMENT_ADDRESS, VtBench
from hil.isobus.vt.errors import PoolErrorCode
from hil.isobus.vt.messages import ECU_TO_VT_PGN, VT_TO_ECU_PGN, Function
from hil.isobus.vt.samples import large_pool
from hil.isobus.vt.server import VT_ADDRESS, VtOptions
from hil.isobus.vt.store import VersionStore

from .pools import IDS, implement_pool, split


def vt_frames(bench: VtBench, function: int, pgn: int = VT_TO_ECU_PGN) -> list[bytes]:
    out = []
    for frame in bench.wire.frames:
        fid = frame.frame.arbitration_id
        if (fid >> 8) & 0x3FF00 == pgn and frame.frame.data[0] == function:
            out.append(bytes(frame.frame.data))
    return out


def kinds(bench: VtBench) -> list[str]:
    return [e.kind for e in bench.vt.events]


def test_status_every_second_from_the_claim() -> None:
    bench = VtBench(client=False)
    bench.run_until(5.0)
    status = [f for f in bench.wire.frames if (f.frame.arbitration_id >> 8) & 0x3FFFF
              == (VT_TO_ECU_PGN | 0xFF) and f.frame.data[0] == Function.VT_STATUS]
    times = [round(f.time_s, 3) for f in status]
    assert times == [0.25, 1.25, 2.25, 3.25, 4.25]
    assert bytes(status[0].frame.data) == bytes([0xFE, 0xFE, 0xFF, 0xFF, 0xFF, 0xFF, 0, 0xFF])


def test_connection_upload_in_several_transfers_then_active() -> None:
    pool = implement_pool()
    bench = VtBench(split(pool, 3))
    bench.run_until(5.0)
    client = bench.client
    assert client is not None and client.state == "connected", client.state
    ws = bench.vt.sessions[IMPLEMENT_ADDRESS]
    assert ws.pool is not None and ws.pool.to_bytes() == pool.to_bytes()
    assert len(ws.pool.raw) == 3
    assert kinds(bench)[:2] == ["connected", "memory"]
    assert kinds(bench).count("transferred") == 3
    assert ws.active_mask == IDS.home and ws.soft_key_mask == IDS.keys
    # the status names the working set and its masks
    status = vt_frames(bench, Function.VT_STATUS)[-1]
    assert status[1] == IMPLEMENT_ADDRESS and status[2:6] == bytes([0xE8, 0x03, 0xD0, 0x07])
    # the connection procedure's answers
    assert vt_frames(bench, Function.GET_MEMORY) == [bytes([0xC0, 4, 0, 0xFF, 0xFF, 0xFF, 0xFF,
                                                            0xFF])]
    hardware = vt_frames(bench, Function.GET_HARDWARE)[0]
    assert int.from_bytes(hardware[4:6], "little") == 480
    assert vt_frames(bench, Function.END_OF_OBJECT_POOL) == [bytes([0x12, 0, 0xFF, 0xFF, 0xFF,
                                                                    0xFF, 0, 0xFF])]


def test_a_100_kb_pool_by_etp_and_a_second_connection_loads_it() -> None:
    pool = large_pool()
    store = VersionStore()
    bench = VtBench([pool.to_bytes()], version_label=b"BIG1", store=store)
    bench.run_until(30.0)
    client = bench.client
    assert client is not None and client.state == "connected" and not client.loaded
    ws = bench.vt.sessions[IMPLEMENT_ADDRESS]
    assert ws.pool is not None and ws.pool.size == pool.size
    assert store.labels(ws.key) == [b"BIG1   "]
    # the VT restarts: the client reconnects and loads the stored version
    bench.vt.restart(bench.now, down_s=5.0)   # a reboot: no status for 5 s
    before = len(vt_frames(bench, Function.OBJECT_POOL_TRANSFER, ECU_TO_VT_PGN))
    bench.run_for(12.0)
    assert client.state == "connected" and client.loaded
    assert "loaded version" in bench.vt.events[-1].detail
    assert len(vt_frames(bench, Function.OBJECT_POOL_TRANSFER, ECU_TO_VT_PGN)) == before


def test_stored_versions_on_disk_outlive_the_vt(tmp_path: pytest.TempPathFactory) -> None:
    pool = implement_pool()
    directory = tmp_path / "vt-store"      # type: ignore[operator]
    bench = VtBench([pool.to_bytes()], version_label=b"V1", store=VersionStore(directory))
    bench.run_until(5.0)
    again = VtBench([pool.to_bytes()], version_label=b"V1", store=VersionStore(directory))
    again.run_until(5.0)
    assert again.client is not None and again.client.loaded
    assert not vt_frames(again, Function.OBJECT_POOL_TRANSFER, ECU_TO_VT_PGN)


def test_a_bad_pool_is_refused_naming_the_object() -> None:
    pool = implement_pool()
    raw = bytearray(pool.to_bytes())
    obj = pool.get(IDS.rate_out)
    assert obj is not None
    # the output number's variable reference (bytes 11-12 of the object) -> a missing object
    raw[obj.offset + 11:obj.offset + 13] = (4444).to_bytes(2, "little")
    bench = VtBench([bytes(raw)])
    bench.run_until(5.0)
    client = bench.client
    assert client is not None and client.state == "refused"
    assert client.refusal is not None
    assert (client.refusal.object_id, client.refusal.parent_id) == (IDS.rate_out, IDS.home)
    assert client.refusal.pool_error_codes == PoolErrorCode.UNKNOWN_REFERENCE
    assert bench.vt.events[-1].kind == "refused" and "4444" in bench.vt.events[-1].detail


def test_not_enough_memory() -> None:
    bench = VtBench([implement_pool().to_bytes()], options=VtOptions(memory_bytes=100))
    bench.run_until(5.0)
    assert bench.client is not None and bench.client.refusal is not None
    assert bench.client.refusal.reason == "not enough memory"


def test_a_silent_working_set_is_gone_after_3_s() -> None:
    bench = VtBench([implement_pool().to_bytes()])
    bench.run_until(3.0)
    assert IMPLEMENT_ADDRESS in bench.vt.sessions
    bench.implement_cf.applications.clear()        # the implement stops talking
    silent_from = bench.vt.sessions[IMPLEMENT_ADDRESS].last_seen_s
    bench.run_for(5.0)
    assert IMPLEMENT_ADDRESS not in bench.vt.sessions
    gone = [e for e in bench.vt.events if e.kind == "timed out"]
    assert len(gone) == 1 and abs(gone[0].time_s - silent_from - 3.0) < 1e-6


def test_versions_5_and_6_and_unsupported_functions() -> None:
    bench = VtBench([implement_pool().to_bytes()], options=VtOptions(version=5))
    bench.run_until(3.0)
    assert vt_frames(bench, Function.GET_MEMORY)[0][1] == 5
    assert bench.client is not None
    bench.client.command(bytes([0xB8, 1, 2, 3, 4, 5, 6, 7]))   # graphics context command
    bench.run_for(0.5)
    assert vt_frames(bench, Function.UNSUPPORTED_FUNCTION)[-1][:2] == bytes([0xFD, 0xB8])
    with pytest.raises(ValueError, match="version 7"):
        VtOptions(version=7)


def test_vt_address_and_name() -> None:
    bench = VtBench(client=False)
    bench.run_until(1.0)
    assert bench.vt.port.address == VT_ADDRESS


@pytest.mark.realtime
def test_in_real_time_on_a_virtual_can_bus() -> None:
    """The same VT and client, each driven in real time by hil.isobus.wire.drive on a
    python-can virtual bus (two threads): connected, pool active, a key press arrives."""
    import threading

    from hil.bus.registry import open_bus
    from hil.isobus.network import IsobusNetwork
    from hil.isobus.vt.bench import IMPLEMENT_ADDRESS as ADDRESS
    from hil.isobus.vt.bench import IMPLEMENT_NAME
    from hil.isobus.vt.client import VtClient
    from hil.isobus.vt.messages import KeyActivation
    from hil.isobus.vt.server import add_vt
    from hil.isobus.wire import drive

    rig, implement = IsobusNetwork(name="rig"), IsobusNetwork(name="implement")
    vt = add_vt(rig)
    cf = implement.add(IMPLEMENT_NAME, ADDRESS, "implement")
    client = VtClient(cf, [implement_pool().to_bytes()])
    cf.run(client)
    rig_bus, implement_bus = open_bus("virtual:vt-realtime"), open_bus("virtual:vt-realtime")
    pressed = threading.Event()

    def press() -> None:
        vt.post(lambda now: vt.key_event(IDS.key_master, KeyActivation.PRESSED, now))
        pressed.set()

    # the durations are time-outs, not timings: each drive ends as soon as its step is done
    # (a shared, loaded machine took more than the 8 s first given here for the connection)
    def run_rig() -> None:
        now = drive(rig, rig_bus, 40.0, until=lambda: bool(vt.active_working_set))
        if vt.active_working_set is not None:
            press()
        drive(rig, rig_bus, 10.0, start_s=now, until=lambda: bool(client.keys))

    thread = threading.Thread(target=run_rig)
    thread.start()
    try:
        drive(implement, implement_bus, 50.0, until=lambda: bool(client.keys))
    finally:
        thread.join()
        rig_bus.shutdown()
        implement_bus.shutdown()
    assert client.state == "connected" and pressed.is_set()
    assert [(k.object_id, k.activation) for k in client.keys] == [
        (IDS.key_master, KeyActivation.PRESSED)]


def test_a_vt_that_starts_after_the_implement_asks_for_its_claim() -> None:
    """The implement claimed its address 2 s before the VT was on the bus: the VT asks for
    the claims when it takes its address, so the implement's NAME is known and its transfer
    answered (the network layer ignores transfers from addresses it never heard claim)."""
    bench = VtBench([implement_pool().to_bytes()], version_label=b"LATE", vt_start_s=2.0)
    bench.wire.nodes = [bench.implement]          # the VT is not on the bus yet
    bench.run_until(2.0)
    bench.wire.nodes.append(bench.rig)
    bench.run_until(8.0)
    assert bench.client is not None and bench.client.state == "connected"
    ws = bench.vt.sessions[IMPLEMENT_ADDRESS]
    assert ws.name is not None and ws.key == ws.name
    requests = [f for f in bench.wire.frames if (f.frame.arbitration_id >> 8) & 0x3FF00
                == 0xEA00 and f.frame.arbitration_id & 0xFF == VT_ADDRESS]
    assert requests and bytes(requests[0].frame.data[:3]) == bytes([0x00, 0xEE, 0x00])


def test_the_vt_client_ignores_a_vt_message_too_short_for_its_function() -> None:
    """A broken or hostile VT's short message (a 2-byte change numeric value, a 3-byte key
    activation) is not an answer: the client ignores it, as the C build does, instead of
    raising IndexError from the implement's stack."""
    from hil.isobus.network import IsobusNetwork
    from hil.isobus.port import Received
    from hil.isobus.vt.bench import IMPLEMENT_NAME
    from hil.isobus.vt.client import _NEEDED, VtClient

    cf = IsobusNetwork(name="implement").add(IMPLEMENT_NAME, IMPLEMENT_ADDRESS, "implement")
    client = VtClient(cf, [implement_pool().to_bytes()])
    client.vt = VT_ADDRESS
    states = ("wait memory", "wait versions", "wait load", "wait end of pool", "connected")
    for function, needed in _NEEDED.items():
        for n in range(1, needed):
            for state in states:
                client.state = state
                data = bytes([function]) + b"\x00" * (n - 1)
                client._on_vt(Received(VT_TO_ECU_PGN, data, VT_ADDRESS, IMPLEMENT_ADDRESS, 1.0))
                assert client.state == state, (hex(function), n, state)
