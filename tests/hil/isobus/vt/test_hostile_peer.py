"""The VT under a hostile or broken working set, on the real network layer in virtual time: what
each peer did used to serve an address without a NAME, keep a working set for a stranger at its
address, grow the VT's records and a working set's transfers without bound, fill the version
store's disk, end the VT (and the serve) on an exception, or freeze it drawing a pool."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.isobus.port import GLOBAL_ADDRESS, Received
from hil.isobus.vt import server as vt_server
from hil.isobus.vt.bench import IMPLEMENT_ADDRESS
from hil.isobus.vt.builder import PoolBuilder
from hil.isobus.vt.errors import PoolErrorCode, VtPoolError
from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.messages import ECU_TO_VT_PGN, Function, pad, u16
from hil.isobus.vt.pool import MAX_DRAWN, ObjectPool
from hil.isobus.vt.server import VT_ADDRESS, VtOptions
from hil.isobus.vt.store import VersionStore

from .hostile_vt import (
    END_OF_POOL,
    GOOD_LABEL,
    PEER_NAMES,
    build,
    change_numeric,
    check_vt,
    claim,
    connection,
    delete_version,
    files_under,
    get_memory,
    keep_alive,
    load_version,
    maintenance,
    raw_vt,
    store_version,
    transfer,
)
from .pools import IDS, implement_pool

PEER = 0x92


def _peer_pool() -> bytes:
    return implement_pool().to_bytes()


def test_a_good_implement_connects_through_the_bench_and_the_checks_hold() -> None:
    # the bench's own connection works when nothing else happens: the checks are made on a
    # run where the VT really activates pools and stores a version
    b = build(groups=connection(PEER, 0.5, _peer_pool(), b"PEER") + keep_alive(PEER, 1.0, 5.0))
    b.wire.run_until(5.0)
    check_vt(b, 5.0)
    assert b.vt.sessions[PEER].pool is not None
    assert b.store.labels(b.vt.sessions[PEER].key) == [b"PEER   "]
    assert b.store.labels(b.vt.sessions[IMPLEMENT_ADDRESS].key) == [GOOD_LABEL + b"   "]


def test_the_checks_fail_a_vt_that_breaks_them() -> None:
    # a working set for the global address, a stranger's working set, a status that paused,
    # a client error, an unbounded record: each makes the checks raise (and is undone)
    b = build(groups=connection(PEER, 0.5, _peer_pool()) + keep_alive(PEER, 1.0, 4.0))
    b.wire.run_until(4.0)
    check_vt(b, 4.0)
    vt, table = b.vt, b.tractor.network.table
    frames, events = list(b.wire.frames), list(vt.events)

    def global_session() -> None:
        vt.sessions[0xFF] = vt.sessions[PEER]

    def strangers_session() -> None:
        table.on_claim(PEER, 1)             # another NAME holds 0x92 now

    def status_pause() -> None:
        b.wire.frames[:] = [f for f in frames if not 1.0 < f.time_s < 2.5]

    def client_error() -> None:
        vt.counts["event client error"] += 1

    def unbounded() -> None:
        vt.events.extend([events[0]] * vt_server.EVENTS_KEPT)

    def undo() -> None:
        vt.sessions.pop(0xFF, None)
        table.forget(PEER)
        table.on_claim(PEER, PEER_NAMES[PEER].value)
        b.wire.frames[:] = frames
        vt.counts["event client error"] = 0
        vt.events[:] = events

    for change in (global_session, strangers_session, status_pause, client_error, unbounded):
        change()
        with pytest.raises(AssertionError):
            check_vt(b, 4.0)
        undo()
        check_vt(b, 4.0)


def test_an_address_that_never_claimed_gets_no_working_set_and_is_logged_as_counts() -> None:
    # 10 addresses that never claimed send maintenance, get memory and commands, 100 a second
    # each, for 2 s: no working set, one line per address and second and a count, their
    # claims asked for at that rate (the VT used to serve them under "NAME unknown")
    raw = [(1.0 + k * 0.01, raw_vt(0xA0 + a, data))
           for a in range(10) for k, data in
           zip(range(200), [maintenance(True), get_memory(100), change_numeric(1, 2)] * 70,
               strict=False)]
    b = build(raw, good=False)
    b.wire.run_until(4.0)
    check_vt(b, 4.0)
    assert b.vt.sessions == {}
    rejected = [e for e in b.vt.events if e.kind == "rejected message"]
    assert 10 <= len(rejected) <= 10 * 3 * 2
    counted = sum(int(e.detail.split()[0]) for e in rejected if "more message" in e.detail)
    assert counted + sum(1 for e in rejected if "more message" not in e.detail) == 2_000
    assert b.vt.counts["rejected"] == 2_000
    requests = [f for f in b.wire.frames if f.sender == 0
                and (f.frame.arbitration_id >> 8) & 0x3FF00 == 0xEA00
                and 0xA0 <= f.frame.arbitration_id >> 8 & 0xFF <= 0xA9]
    assert 10 <= len(requests) <= 10 * 3


def test_the_global_and_null_addresses_never_get_a_working_set() -> None:
    # on the network they are dropped; the VT refuses them on its own as well
    from .test_server_fuzz import FakePort
    port = FakePort()
    port.name_of = lambda address: 0x1234      # type: ignore[method-assign]
    vt = vt_server.VirtualTerminalServer(port)  # type: ignore[arg-type]
    vt.tick(0.0)
    for handler in port.handlers[ECU_TO_VT_PGN]:
        for source in (0xFF, 0xFE):
            handler(Received(ECU_TO_VT_PGN, maintenance(True), source, VT_ADDRESS, 0.1))
            handler(Received(ECU_TO_VT_PGN, get_memory(10), source, VT_ADDRESS, 0.1))
    assert vt.sessions == {}
    assert not [s for s in port.sent if s[2] in (0xFE, 0xFF) and s[1][0] == Function.GET_MEMORY]


def test_a_working_set_belongs_to_its_name_a_newcomer_at_its_address_gets_nothing_of_it() -> None:
    # at 5 s a lower NAME claims the good implement's address and sends commands from it: the
    # VT used to apply them to the implement's pool and keep showing it as the newcomer's
    setpoint = change_numeric(IDS.rate_var, 99_999)
    raw = [(5.0, claim(IMPLEMENT_ADDRESS, name=0x1000)),
           *[(5.2 + k * 0.05, raw_vt(IMPLEMENT_ADDRESS, setpoint)) for k in range(20)]]
    b = build(raw)
    b.wire.run_until(4.9)
    ws = b.vt.sessions[IMPLEMENT_ADDRESS]
    assert ws.pool is not None
    b.wire.run_until(7.0)
    ended = [e for e in b.vt.events if e.kind == "session ended"]
    assert [(e.time_s, e.address) for e in ended] == [(5.0, IMPLEMENT_ADDRESS)]
    assert "0000000000001000 claimed 0x84" in ended[0].detail
    assert ws.pool.get(IDS.rate_var)["value"] == 2500, "the newcomer changed the pool"
    newcomer = b.vt.sessions.get(IMPLEMENT_ADDRESS)
    assert newcomer is not None and newcomer.name == 0x1000 and newcomer.pool is None
    status = b.vt_frames(Function.VT_STATUS, GLOBAL_ADDRESS)[-1][1]
    assert status[1] == 0xFE, "the VT still shows the newcomer as the active working set"
    check_vt(b, 7.0, good_connects=False)


def _command_flood(n: int) -> None:
    pool = _peer_pool()
    end = 3.0 + n / 1000
    flood = [(2.0 + k * 0.001, PEER, ECU_TO_VT_PGN, change_numeric(IDS.rate_var, k), VT_ADDRESS)
             for k in range(n)]
    b = build(groups=connection(PEER, 0.3, pool) + keep_alive(PEER, 1.0, end) + flood,
              good=False)
    b.wire.run_until(end)
    check_vt(b, end)
    assert b.vt.counts["commands"] == n
    assert len(b.vt.commands) <= vt_server.COMMANDS_KEPT
    assert b.vt.commands[0].detail == f"numeric value {IDS.rate_var} = 0"
    assert b.vt.commands[-1].detail == f"numeric value {IDS.rate_var} = {n - 1}"
    assert len(b.vt_frames(Function.CHANGE_NUMERIC_VALUE, PEER)) == n


def test_a_flood_of_commands_keeps_the_vts_records_bounded(monkeypatch) -> None:
    # a connected working set sends 1,500 commands (1,000 a second) to a VT that keeps 1,000
    # records: it answers each, counts them all and keeps the first and the latest (it used
    # to keep every one)
    monkeypatch.setattr(vt_server, "COMMANDS_KEPT", 1_000)
    _command_flood(1_500)


@pytest.mark.slow
def test_a_flood_of_20_000_commands_keeps_the_vts_records_bounded() -> None:
    _command_flood(20_000)


def test_transfers_past_the_vts_memory_are_dropped_and_refused_at_the_end() -> None:
    # 40 transfers of 1 kB against a VT of 10 kB, no end of object pool until the last: the
    # VT used to keep them all until the end of object pool
    chunk = transfer(_peer_pool()[:1000])
    groups = [(0.5, PEER, ECU_TO_VT_PGN, maintenance(True), VT_ADDRESS),
              *[(0.6 + k * 0.1, PEER, ECU_TO_VT_PGN, chunk, VT_ADDRESS) for k in range(40)],
              (5.0, PEER, ECU_TO_VT_PGN, END_OF_POOL, VT_ADDRESS),
              *keep_alive(PEER, 1.0, 6.0)]
    b = build(groups=groups, options=VtOptions(memory_bytes=10_000), good=False)
    b.wire.run_until(4.9)
    ws = b.vt.sessions[PEER]
    assert sum(map(len, ws.transfers)) <= 10_000
    b.wire.run_until(6.0)
    end = b.vt_frames(Function.END_OF_OBJECT_POOL, PEER)
    assert [d[1] for _, d in end] == [0x02], "out of memory"
    assert ws.transfers == []
    check_vt(b, 6.0, good_connects=False)


def test_memory_is_the_vts_whole_and_working_sets_share_it() -> None:
    # a second working set is told what the first leaves: 8 kB of 10 kB taken
    pool = _peer_pool()
    groups = connection(PEER, 0.5, pool) + keep_alive(PEER, 1.0, 5.0) + [
        (3.0, 0x93, ECU_TO_VT_PGN, maintenance(True), VT_ADDRESS),
        (3.1, 0x93, ECU_TO_VT_PGN, get_memory(10_000 - len(pool) + 1), VT_ADDRESS),
        (3.2, 0x93, ECU_TO_VT_PGN, get_memory(10_000 - len(pool)), VT_ADDRESS)]
    b = build(groups=groups, options=VtOptions(memory_bytes=10_000), good=False)
    b.wire.run_until(5.0)
    answers = [d[2] for _, d in b.vt_frames(Function.GET_MEMORY, 0x93)]
    assert answers == [1, 0]          # not enough, then enough


def test_the_version_store_is_bounded_and_refuses_with_insufficient_memory(
        tmp_path: Path) -> None:
    # a working set stores 50 versions under different labels: the store keeps its bound (8 a
    # NAME here) and answers the rest "insufficient memory" (it used to keep them all)
    store = VersionStore(tmp_path / "vt-store")
    pool = _peer_pool()
    stores = [(2.5 + k * 0.02, PEER, ECU_TO_VT_PGN, store_version(b"V%03d" % k), VT_ADDRESS)
              for k in range(50)]
    b = build(groups=connection(PEER, 0.3, pool) + keep_alive(PEER, 1.0, 5.0) + stores,
              options=VtOptions(store_max_versions_per_name=8), store=store, good=False)
    b.wire.run_until(5.0)
    errors = [d[5] for _, d in b.vt_frames(Function.STORE_VERSION, PEER)]
    assert errors == [0] * 8 + [0x04] * 42
    assert len(list((tmp_path / "vt-store").iterdir())) == 8
    assert any(e.kind == "store refused" and "keeps 8 versions" in e.detail
               for e in b.vt.events)
    # deleting one makes room for another
    b.senders[PEER].plan += [(5.1, ECU_TO_VT_PGN, delete_version(b"V000"), VT_ADDRESS),
                             (5.2, ECU_TO_VT_PGN, store_version(b"V049"), VT_ADDRESS)]
    b.wire.run_until(6.0)
    assert [d[5] for _, d in b.vt_frames(Function.DELETE_VERSION, PEER)] == [0]
    assert [d[5] for _, d in b.vt_frames(Function.STORE_VERSION, PEER)][-1] == 0
    check_vt(b, 6.0, good_connects=False)


def test_the_store_bound_on_bytes() -> None:
    store = VersionStore()
    pool = _peer_pool()
    limit = 2 * (len(pool) + 4) + 10
    stores = [(2.5 + k * 0.05, PEER, ECU_TO_VT_PGN, store_version(b"B%d" % k), VT_ADDRESS)
              for k in range(3)]
    b = build(groups=connection(PEER, 0.3, pool) + keep_alive(PEER, 1.0, 4.0) + stores,
              options=VtOptions(store_max_bytes=limit), store=store, good=False)
    b.wire.run_until(4.0)
    assert [d[5] for _, d in b.vt_frames(Function.STORE_VERSION, PEER)] == [0, 0, 0x04]
    assert store.bytes <= limit


def test_hostile_labels_stay_file_names_inside_the_store(tmp_path: Path) -> None:
    # labels with path characters are stored, listed and loaded as labels; every file is in
    # the store's directory, named by hex digits
    root = tmp_path / "out"
    store = VersionStore(root / "vt-store")
    labels = [b"../../x", b"/etc/pa", b"..\\..\\a", b"\x00\x00/\x00", b"a/../..", b"*      "]
    extended = b"../" * 10 + b".."
    pool = _peer_pool()
    groups = connection(PEER, 0.3, pool) + keep_alive(PEER, 1.0, 5.0)
    groups += [(2.5 + k * 0.05, PEER, ECU_TO_VT_PGN, store_version(label), VT_ADDRESS)
               for k, label in enumerate(labels)]
    groups += [(3.0, PEER, ECU_TO_VT_PGN, store_version(extended, extended=True), VT_ADDRESS),
               (3.5, PEER, ECU_TO_VT_PGN, load_version(b"../../x"), VT_ADDRESS)]
    b = build(groups=groups, store=store, good=False)
    b.wire.run_until(5.0)
    files = files_under(tmp_path)
    assert len(files) == len(labels) + 1
    for f in files:
        assert f.parent == root / "vt-store" and f.suffix == ".vtp"
        assert set(f.stem) <= set("0123456789abcdefABCDEF-")
    again = VersionStore(root / "vt-store")
    key = b.vt.sessions[PEER].key
    assert sorted(again.labels(key)) == sorted(label.ljust(7) for label in labels)
    assert again.labels(key, extended=True) == [extended]
    assert [d[5] for _, d in b.vt_frames(Function.LOAD_VERSION, PEER)] == [0]


def test_a_disk_that_refuses_the_store_is_answered_not_the_end_of_the_vt(tmp_path: Path,
                                                                          ) -> None:
    # the store's directory cannot be made (a file is in its way): the store version is
    # answered "any other error" and the VT goes on (the OSError used to end it)
    (tmp_path / "vt-store").write_text("in the way")
    store = VersionStore(tmp_path / "vt-store" / "inner")
    pool = _peer_pool()
    groups = connection(PEER, 0.3, pool, b"DISK") + keep_alive(PEER, 1.0, 5.0)
    b = build(groups=groups, store=store, good=False)
    b.wire.run_until(5.0)
    assert [d[5] for _, d in b.vt_frames(Function.STORE_VERSION, PEER)] == [0x08]
    assert any(e.kind == "store refused" and "cannot write" in e.detail for e in b.vt.events)
    check_vt(b, 5.0, good_connects=False)


def _pool_with(extra) -> bytes:
    b = PoolBuilder()
    font = b.font()
    text = b.output_string("x", font=font)
    parts = extra(b, text)
    mask = b.data_mask(parts)
    b.working_set(mask)
    return b"".join(_serialised(b))


def _serialised(builder: PoolBuilder) -> list[bytes]:
    from hil.isobus.vt.codec import serialise_object
    return [serialise_object(o) for o in builder.objects]


def test_a_pool_with_an_object_inside_itself_is_refused_naming_it() -> None:
    # a container listing itself: drawn 32 levels deep twice a level it was 4 billion objects
    def cycle(b: PoolBuilder, text: int) -> list:
        box = b.container([(text, 0, 0), (500, 0, 0), (500, 5, 5)], 50, 50, object_id=500)
        return [(box, 0, 0)]

    with pytest.raises(VtPoolError) as err:
        ObjectPool.from_transfers([_pool_with(cycle)])
    assert err.value.code == PoolErrorCode.ANY_OTHER
    assert "inside itself" in str(err.value)


def test_a_pool_that_draws_too_many_objects_is_refused_naming_it() -> None:
    # 20 containers, each listing the next one twice: 2^20 objects drawn from 20 objects
    def fan(b: PoolBuilder, text: int) -> list:
        inner = text
        for _ in range(20):
            inner = b.container([(inner, 0, 0), (inner, 1, 1)], 50, 50)
        return [(inner, 0, 0)]

    with pytest.raises(VtPoolError) as err:
        ObjectPool.from_transfers([_pool_with(fan)])
    assert err.value.code == PoolErrorCode.ANY_OTHER
    assert f"more than the VT's {MAX_DRAWN}" in str(err.value)


def test_the_refused_pool_is_answered_with_the_error_code_and_the_vt_goes_on() -> None:
    def cycle(b: PoolBuilder, text: int) -> list:
        box = b.container([(text, 0, 0), (500, 0, 0), (500, 5, 5)], 50, 50, object_id=500)
        return [(box, 0, 0)]

    pool = _pool_with(cycle)
    b = build(groups=connection(PEER, 0.5, pool) + keep_alive(PEER, 1.0, 5.0))
    b.wire.run_until(5.0)
    end = b.vt_frames(Function.END_OF_OBJECT_POOL, PEER)
    assert [(d[1], d[6]) for _, d in end] == [(0x01, int(PoolErrorCode.ANY_OTHER))]
    check_vt(b, 5.0)


def test_an_object_pointer_set_to_contain_itself_is_refused() -> None:
    # a pointer inside a container, set to that container: an invalid value (it used to be
    # taken, and the mask then drew itself 32 levels deep)
    b = PoolBuilder()
    font = b.font()
    text = b.output_string("x", font=font)
    pointer = b.add(ObjectType.OBJECT_POINTER, value=text)
    box = b.container([(pointer, 0, 0), (pointer, 10, 10)], 50, 50)
    mask = b.data_mask([(box, 0, 0)])
    b.working_set(mask)
    pool = b"".join(_serialised(b))
    groups = connection(PEER, 0.5, pool) + keep_alive(PEER, 1.0, 5.0) + [
        (3.0, PEER, ECU_TO_VT_PGN, change_numeric(pointer, box), VT_ADDRESS),
        (3.1, PEER, ECU_TO_VT_PGN, change_numeric(pointer, mask), VT_ADDRESS),
        (3.2, PEER, ECU_TO_VT_PGN, change_numeric(pointer, font), VT_ADDRESS)]
    bench = build(groups=groups, good=False)
    bench.wire.run_until(5.0)
    errors = [d[3] for _, d in bench.vt_frames(Function.CHANGE_NUMERIC_VALUE, PEER)]
    assert errors == [0x02, 0x02, 0]
    assert bench.vt.sessions[PEER].obj(pointer)["value"] == font
    check_vt(bench, 5.0, good_connects=False)


def _macro_pool(commands: bytes) -> tuple[bytes, int]:
    b = PoolBuilder()
    font = b.font()
    macro = b.macro(commands, object_id=7)
    mask = b.data_mask([(b.output_string("x", font=font), 0, 0)])
    b.working_set(mask)
    return b"".join(_serialised(b)), macro


def test_a_macro_that_runs_itself_is_bounded() -> None:
    # a macro executing itself three times, 8 deep: 6,561 commands for one execute macro;
    # the VT runs MAX_MACRO_COMMANDS and answers "any other error"
    run_self = pad([Function.EXECUTE_MACRO, 7])
    pool, macro = _macro_pool(run_self * 3)
    groups = connection(PEER, 0.5, pool) + keep_alive(PEER, 1.0, 4.0) + [
        (3.0, PEER, ECU_TO_VT_PGN, pad([Function.EXECUTE_MACRO, macro]), VT_ADDRESS)]
    b = build(groups=groups, good=False)
    b.wire.run_until(4.0)
    responses = b.vt_frames(Function.EXECUTE_MACRO, PEER)
    assert [d[3] for _, d in responses] == [0x04]
    check_vt(b, 4.0, good_connects=False)


def test_a_macro_cut_short_inside_a_change_string_value_is_no_error() -> None:
    # its last command is 2 bytes of a change string value: reading its length raised
    # IndexError, which ended the VT (and the serve)
    pool, macro = _macro_pool(bytes([Function.CHANGE_STRING_VALUE, 0x01]))
    groups = connection(PEER, 0.5, pool) + keep_alive(PEER, 1.0, 4.0) + [
        (3.0, PEER, ECU_TO_VT_PGN, pad([Function.EXECUTE_MACRO, macro]), VT_ADDRESS)]
    b = build(groups=groups, good=False)
    b.wire.run_until(4.0)
    assert [d[3] for _, d in b.vt_frames(Function.EXECUTE_MACRO, PEER)] == [0]
    check_vt(b, 4.0, good_connects=False)


def test_an_exception_from_a_working_sets_input_ends_that_working_set_only() -> None:
    # whatever raises while a working set's message is handled (here: drawing its screen)
    # ends that working set, named in a "client error" event; the VT, the TECU and the good
    # implement go on (it used to raise out of the network, ending the serve)
    b = build(groups=connection(PEER, 0.5, _peer_pool()) + keep_alive(PEER, 1.0, 6.0))

    def draw(ws, time_s, reason) -> None:
        if ws.address == PEER and ws.pool is not None:
            raise ZeroDivisionError("a drawing bug")

    b.vt.on_change.insert(0, draw)
    b.wire.run_until(6.0)
    errors = [e for e in b.vt.events if e.kind == "client error"]
    assert len(errors) == 1 and errors[0].address == PEER
    assert "ZeroDivisionError: a drawing bug" in errors[0].detail
    b.vt.counts["event client error"] = 0       # the one the test made
    b.vt.events[:] = [e for e in b.vt.events if e.kind != "client error"]
    check_vt(b, 6.0)


def test_the_vt_that_loses_its_address_says_so() -> None:
    # a lower NAME claims 0x26: the VT (not self-configurable) yields as ISO 11783-5 says,
    # its working sets end, and its events say why (it used to fall silent without a word)
    b = build([(4.0, claim(VT_ADDRESS, name=0x1))])
    b.wire.run_until(6.0)
    lost = [e for e in b.vt.events if e.kind == "address lost"]
    assert len(lost) == 1 and "lost 0x26 to NAME 0000000000000001" in lost[0].detail
    assert b.vt.sessions == {}
    assert any(e.kind == "session ended" and e.address == IMPLEMENT_ADDRESS
               for e in b.vt.events)
    check_vt(b, 6.0, good_connects=False)


def test_commands_before_a_pool_are_refused_and_store_before_a_pool_is_any_other_error() -> None:
    groups = [(0.5, PEER, ECU_TO_VT_PGN, maintenance(True), VT_ADDRESS),
              (0.6, PEER, ECU_TO_VT_PGN, change_numeric(1, 1), VT_ADDRESS),
              (0.7, PEER, ECU_TO_VT_PGN, store_version(b"NOPOOL"), VT_ADDRESS),
              (0.8, PEER, ECU_TO_VT_PGN, load_version(b"NOPOOL"), VT_ADDRESS),
              (0.9, PEER, ECU_TO_VT_PGN, pad([Function.HIDE_SHOW]) + u16(1), VT_ADDRESS),
              *keep_alive(PEER, 1.0, 3.0)]
    b = build(groups=groups)
    b.wire.run_until(3.0)
    assert [d[5] for _, d in b.vt_frames(Function.STORE_VERSION, PEER)] == [0x08]
    assert [d[5] for _, d in b.vt_frames(Function.LOAD_VERSION, PEER)] == [0x02]
    assert b.vt.sessions[PEER].pool is None
    check_vt(b, 3.0)


def test_a_flood_of_commands_before_a_pool_is_nacked_at_a_bounded_rate() -> None:
    # 300 commands before any pool, 100 a second: each recorded, a NACK to everyone at most
    # once a second (it used to be one per frame)
    groups = [(0.5, PEER, ECU_TO_VT_PGN, maintenance(True), VT_ADDRESS),
              *[(1.0 + k * 0.01, PEER, ECU_TO_VT_PGN, change_numeric(1, k), VT_ADDRESS)
                for k in range(300)],
              *keep_alive(PEER, 1.0, 4.5)]
    b = build(groups=groups, good=False)
    b.wire.run_until(4.5)
    nacks = [f for f in b.wire.frames if f.sender == 0
             and (f.frame.arbitration_id >> 8) & 0x3FF00 == 0xE800 and f.frame.data[4] == PEER]
    assert 3 <= len(nacks) <= 4
    assert b.vt.counts["commands"] == 300
    assert b.vt.counts["nacks not sent"] == 300 - len(nacks)
    check_vt(b, 4.5, good_connects=False)
