"""The Task Controller server against scripted clients through a fake port of whole groups."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.isobus import ddi
from hil.isobus import process_data as pd
from hil.isobus.ddop import (
    ActivationError,
    DeviceElement,
    ElementType,
    ObjectPool,
    PoolError,
    ProcessData,
    TriggerMethod,
)
from hil.isobus.ddop.samples import section_control_pool
from hil.isobus.port import GLOBAL_ADDRESS, Handler, Received
from hil.isobus.process_data import AckError, Command, ElementCommand
from hil.isobus.tc import (
    EventKind,
    PoolStore,
    ServerOptions,
    SetpointRequest,
    TaskControllerServer,
    TriggerPlan,
    constant_setpoints,
)

TC = 0xF7
CLIENT = 0x81
NAME = 0xA00C80000AE00002


class FakePort:
    """An IsobusPort that records what is sent and delivers whole groups to subscribers."""

    def __init__(self, address: int | None = TC, names: dict[int, int] | None = None) -> None:
        self._address = address
        self.sent: list[tuple[int, bytes, int, int]] = []
        self.handlers: dict[int, list[Handler]] = defaultdict(list)
        self.names = names if names is not None else {CLIENT: NAME}

    @property
    def address(self) -> int | None:
        return self._address

    def send(self, pgn: int, data: bytes, destination: int = GLOBAL_ADDRESS,
             priority: int = 6) -> None:
        self.sent.append((pgn, bytes(data), destination, priority))

    def subscribe(self, pgn: int, handler: Handler) -> None:
        self.handlers[pgn].append(handler)

    def name_of(self, address: int) -> int | None:
        return self.names.get(address)

    def deliver(self, pgn: int, data: bytes, time_s: float, source: int = CLIENT,
                destination: int = TC) -> None:
        for handler in self.handlers[pgn]:
            handler(Received(pgn, bytes(data), source, destination, time_s))

    def take(self) -> list[tuple[int, bytes, int, int]]:
        out, self.sent = self.sent, []
        return out


class Client:
    """A scripted TC client: sends messages at given times and reads the TC's answers."""

    def __init__(self, port: FakePort, address: int = CLIENT) -> None:
        self.port = port
        self.address = address

    def send(self, message: pd.ProcessDataMessage, t: float) -> list[pd.ProcessDataMessage]:
        self.port.take()
        self.port.deliver(pd.PROCESS_DATA_PGN, pd.encode(message), t, self.address)
        return self.replies()

    def replies(self) -> list[pd.ProcessDataMessage]:
        return [pd.decode(data) for pgn, data, dest, _ in self.port.take()
                if pgn == pd.PROCESS_DATA_PGN and dest == self.address]

    def working_set_master(self, t: float) -> list[pd.ProcessDataMessage]:
        self.port.take()
        self.port.deliver(pd.WORKING_SET_MASTER_PGN,
                          pd.encode_working_set_master(pd.WorkingSetMaster(1)), t, self.address,
                          GLOBAL_ADDRESS)
        return self.replies()

    def connect(self, pool: ObjectPool, t: float, *, transfer: bool = True,
                ) -> pd.ObjectPoolActivateResponse:
        self.working_set_master(t)
        self.send(pd.Version(4), t)
        self.send(pd.RequestVersion(), t)
        self.send(pd.RequestStructureLabel(), t)
        self.send(pd.RequestLocalizationLabel(), t)
        if transfer:
            raw = pool.to_bytes()
            assert self.send(pd.RequestObjectPoolTransfer(len(raw)), t) == [
                pd.RequestObjectPoolTransferResponse(True)]
            assert self.send(pd.ObjectPoolTransfer(raw), t) == [
                pd.ObjectPoolTransferResponse(0, len(raw))]
        (answer,) = self.send(pd.ObjectPoolActivate(True), t)
        assert isinstance(answer, pd.ObjectPoolActivateResponse)
        return answer


def _server(port: FakePort, **kwargs: object) -> TaskControllerServer:
    return TaskControllerServer(port, **kwargs)  # type: ignore[arg-type]


def _run(server: TaskControllerServer, port: FakePort, t0: float, t1: float, *,
         client_task: bool = True, step: float = 0.1) -> list[tuple[float, int, bytes, int]]:
    """Tick from t0 to t1, the client sending its task message every 2 s; what the TC sent."""
    out = []
    n = round((t1 - t0) / step)
    for i in range(n + 1):
        t = round(t0 + i * step, 6)
        if client_task and i % round(2.0 / step) == 0:
            port.deliver(pd.PROCESS_DATA_PGN, pd.encode(pd.ClientTask(True)), t)
        server.tick(t)
        out += [(t, pgn, data, dest) for pgn, data, dest, _ in port.take()]
    return out


def _statuses(sent: list[tuple[float, int, bytes, int]]) -> list[float]:
    return [t for t, pgn, data, dest in sent
            if pgn == pd.PROCESS_DATA_PGN and data[0] == 0xFE and dest == GLOBAL_ADDRESS]


# --- status, version, working-set master ------------------------------------------------------

def test_status_every_two_seconds_from_the_first_tick() -> None:
    port = FakePort()
    server = _server(port)
    sent = _run(server, port, 0.0, 10.0, client_task=False)
    assert _statuses(sent) == [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]
    # its first message asks everyone's claim (clients on the bus before the TC); then status
    assert sent[0][1:] == (0xEA00, b"\x00\xee\x00", GLOBAL_ADDRESS)
    assert sent[1][2] == bytes([0xFE, 0xFF, 0xFF, 0xFF, 0x00, 0x00, 0x00, 0xFF])
    assert port.sent == []


def test_a_session_needs_a_claimed_name_whose_claim_the_tc_then_asks() -> None:
    port = FakePort()
    server = _server(port)
    server.tick(0.0)
    port.take()
    wsm = pd.encode_working_set_master(pd.WorkingSetMaster(1))

    def working_set_master(t: float) -> list[tuple[int, bytes, int]]:
        port.deliver(pd.WORKING_SET_MASTER_PGN, wsm, t, 0x90, GLOBAL_ADDRESS)
        return [(pgn, data, dest) for pgn, data, dest, _ in port.take()]

    # 0x90 never claimed, as far as the TC heard: no session; its claim is asked, at most
    # once a second
    assert working_set_master(0.1) == [(0xEA00, b"\x00\xee\x00", 0x90)]
    assert server.sessions == {} and server.events[-1].kind == EventKind.REJECTED_MESSAGE
    assert working_set_master(0.2) == []
    assert working_set_master(1.2) == [(0xEA00, b"\x00\xee\x00", 0x90)]
    port.names[0x90] = 0xA000_8000_0000_0090      # its claim arrives
    assert working_set_master(1.3) == []
    assert server.sessions[0x90].name == 0xA000_8000_0000_0090


def test_nothing_is_sent_before_the_address_is_claimed() -> None:
    port = FakePort(address=None)
    server = _server(port)
    server.tick(0.0)
    assert port.sent == []


def test_working_set_master_opens_a_session_and_the_version_exchange_is_the_standards() -> None:
    # ISO 11783-10: the client asks the TC's version first (after the TC status and its
    # working-set master); the TC answers and then asks the client's, once. A TC that asks at
    # the working-set master makes AgIsoStack++'s client warn "Server requested version
    # information at a strange time" (it is not yet waiting for the TC's request).
    port = FakePort()
    server = _server(port, options=ServerOptions(booms=2, sections=36, channels=3,
                                                 options=0x1F))
    client = Client(port)
    assert client.working_set_master(0.0) == []
    assert CLIENT in server.sessions and server.sessions[CLIENT].name == NAME
    assert client.send(pd.RequestVersion(), 0.1) == [pd.Version(4, 0x1F, 2, 36, 3),
                                                     pd.RequestVersion()]
    assert client.send(pd.Version(4, 0x10, 1, 4, 1), 0.2) == []
    assert server.sessions[CLIENT].version == 4
    # once the client's version is known, the TC does not ask it again
    assert client.send(pd.RequestVersion(), 0.3) == [pd.Version(4, 0x1F, 2, 36, 3)]
    assert [e.kind for e in server.events] == [EventKind.CONNECTED, EventKind.VERSION]


def test_the_tc_asks_the_clients_version_once_even_unanswered() -> None:
    port = FakePort()
    _server(port)
    client = Client(port)
    client.working_set_master(0.0)
    assert pd.RequestVersion() in client.send(pd.RequestVersion(), 0.1)
    assert client.send(pd.RequestVersion(), 0.2) == [
        pd.Version(4, pd.VersionOption.DOCUMENTATION, 1, 16, 1)]


def test_version_request_before_the_clients_version_asks_back() -> None:
    port = FakePort()
    _server(port)
    client = Client(port)
    client.working_set_master(0.0)
    assert client.send(pd.RequestVersion(), 0.1) == [
        pd.Version(4, pd.VersionOption.DOCUMENTATION, 1, 16, 1), pd.RequestVersion()]


def test_process_data_before_the_working_set_master_is_nacked() -> None:
    port = FakePort()
    server = _server(port)
    port.deliver(pd.PROCESS_DATA_PGN, pd.encode(pd.RequestStructureLabel()), 0.0)
    ((pgn, data, dest, _),) = port.take()
    assert (pgn, dest) == (0xE800, GLOBAL_ADDRESS)
    assert data == bytes([0x01, 0xFF, 0xFF, 0xFF, CLIENT, 0x00, 0xCB, 0x00])
    assert server.events[-1].kind == EventKind.REJECTED_MESSAGE


def test_the_nack_can_be_addressed_to_the_client_for_peers_that_need_it() -> None:
    port = FakePort()
    _server(port, nack_to_client=True)
    port.deliver(pd.PROCESS_DATA_PGN, pd.encode(pd.RequestStructureLabel()), 0.0)
    ((pgn, data, dest, _),) = port.take()
    assert (pgn, dest, data[4]) == (0xE800, CLIENT, CLIENT)


def test_language_command_on_request() -> None:
    port = FakePort()
    _server(port)
    port.deliver(0xEA00, (0xFE0F).to_bytes(3, "little"), 0.0)
    assert port.take() == [(0xFE0F, b"en\x40\x00\x00\x00\xff\xff", GLOBAL_ADDRESS, 5)]
    port.deliver(0xEA00, (0xFECA).to_bytes(3, "little"), 0.0)  # DM1: not the TC's to answer
    assert port.take() == []
    quiet = FakePort()
    _server(quiet, language_command=None)
    quiet.deliver(0xEA00, (0xFE0F).to_bytes(3, "little"), 0.0)
    assert quiet.take() == []


def test_malformed_process_data_is_recorded_not_raised() -> None:
    port = FakePort()
    server = _server(port)
    Client(port).working_set_master(0.0)
    port.deliver(pd.PROCESS_DATA_PGN, b"\x03\x00", 0.1)
    assert server.events[-1].kind == EventKind.REJECTED_MESSAGE
    assert "2 bytes" in server.events[-1].detail


# --- the pool: transfer, activate, refuse -------------------------------------------------------

def test_a_full_session_activates_and_process_data_flows() -> None:
    pool = section_control_pool(sections=4)
    product = next(e for e in pool.elements if e.element_type == ElementType.BIN)
    boom = next(e for e in pool.elements if e.designator == b"Boom")
    sections_on = ddi.pack_condensed_work_state([1, 1, 0, 1])
    port = FakePort()
    server = _server(port, setpoints=constant_setpoints({
        ddi.SETPOINT_MASS_PER_AREA_RATE: 25_000,
        ddi.SETPOINT_CONDENSED_WORK_STATE_1_16: sections_on}))
    client = Client(port)
    assert client.connect(pool, 0.0) == pd.ObjectPoolActivateResponse(0)
    assert server.sessions[CLIENT].active

    sent = _run(server, port, 0.1, 0.1)
    commands = [pd.decode(data) for _, pgn, data, dest in sent if dest == CLIENT]
    triggers = [c for c in commands if isinstance(c, ElementCommand)
                and c.command in pd.MEASUREMENT_COMMANDS]
    assert triggers == TriggerPlan().commands(pool)
    assert ElementCommand(Command.MEASUREMENT_TIME_INTERVAL, product.element_number,
                          ddi.ACTUAL_MASS_PER_AREA_RATE, 1000) in triggers
    assert ElementCommand(Command.MEASUREMENT_CHANGE_THRESHOLD, product.element_number,
                          ddi.ACTUAL_MASS_PER_AREA_RATE, 1) in triggers
    setpoints = [c for c in commands if isinstance(c, ElementCommand)
                 and c.command == Command.VALUE]
    assert setpoints == [
        ElementCommand(Command.VALUE, boom.element_number,
                       ddi.SETPOINT_CONDENSED_WORK_STATE_1_16, sections_on - 2**32),
        ElementCommand(Command.VALUE, product.element_number, ddi.SETPOINT_MASS_PER_AREA_RATE,
                       25_000),
    ]
    assert setpoints[0].unsigned == sections_on

    # values the client sends are logged with time, element, DDI and value
    assert client.send(ElementCommand(Command.VALUE, product.element_number,
                                      ddi.ACTUAL_MASS_PER_AREA_RATE, 24_500), 0.5) == []
    assert client.send(ElementCommand(Command.SET_VALUE_AND_ACKNOWLEDGE, 0,
                                      ddi.ACTUAL_WORK_STATE, 1), 0.6) == [
        pd.ProcessDataAcknowledge(0, ddi.ACTUAL_WORK_STATE, AckError.NONE,
                                  Command.SET_VALUE_AND_ACKNOWLEDGE)]
    logged = [(v.time_s, v.element, v.ddi, v.value) for v in server.values]
    assert logged == [(0.5, product.element_number, ddi.ACTUAL_MASS_PER_AREA_RATE, 24_500),
                      (0.6, 0, ddi.ACTUAL_WORK_STATE, 1)]
    kinds = [e.kind for e in server.events if e.kind != EventKind.ADDRESS_CLAIMED]
    assert kinds[-2:] == [EventKind.POOL_TRANSFERRED, EventKind.ACTIVATED]


def test_set_points_are_sent_on_change_and_refreshed_when_asked() -> None:
    pool = section_control_pool(sections=1)
    product = next(e for e in pool.elements if e.element_type == ElementType.BIN)
    rate = {"value": 10_000}

    def source(request: SetpointRequest) -> int | None:
        return rate["value"] if request.ddi == ddi.SETPOINT_MASS_PER_AREA_RATE else None

    port = FakePort()
    server = _server(port, setpoints=source, setpoint_refresh_s=5.0)
    Client(port).connect(pool, 0.0)

    def rates(sent: list[tuple[float, int, bytes, int]]) -> list[tuple[float, int]]:
        out = []
        for t, _, data, dest in sent:
            msg = pd.decode(data) if dest == CLIENT else None
            if isinstance(msg, ElementCommand) and msg.ddi == ddi.SETPOINT_MASS_PER_AREA_RATE:
                assert msg.element == product.element_number
                out.append((t, msg.value))
        return out

    assert rates(_run(server, port, 0.1, 3.0)) == [(0.1, 10_000)]
    rate["value"] = 12_000
    assert rates(_run(server, port, 3.1, 5.0)) == [(3.1, 12_000)]
    assert rates(_run(server, port, 5.1, 8.5)) == [(8.1, 12_000)]


def test_value_commands_on_unknown_elements_or_ddis_are_acknowledged_with_errors() -> None:
    port = FakePort()
    server = _server(port)
    client = Client(port)
    client.connect(section_control_pool(sections=1), 0.0)
    assert client.send(ElementCommand(Command.VALUE, 99, 7, 1), 0.1) == [
        pd.ProcessDataAcknowledge(99, 7, AckError.INVALID_ELEMENT_NUMBER, Command.VALUE)]
    assert client.send(ElementCommand(Command.VALUE, 0, 6, 1), 0.2) == [
        pd.ProcessDataAcknowledge(0, 6, AckError.DDI_NOT_SUPPORTED_BY_ELEMENT, Command.VALUE)]
    assert client.send(ElementCommand(Command.MEASUREMENT_TIME_INTERVAL, 0, 141, 100), 0.3) == [
        pd.ProcessDataAcknowledge(0, 141, AckError.COMMAND_NOT_SUPPORTED,
                                  Command.MEASUREMENT_TIME_INTERVAL)]
    assert server.values == []


def test_client_acknowledgements_are_recorded() -> None:
    port = FakePort()
    server = _server(port)
    client = Client(port)
    client.connect(section_control_pool(sections=1), 0.0)
    client.send(pd.ProcessDataAcknowledge(2, 7, AckError.TRIGGER_METHOD_NOT_SUPPORTED,
                                          Command.MEASUREMENT_DISTANCE_INTERVAL), 0.4)
    (ack,) = server.acknowledgements
    assert (ack.element, ack.ddi, ack.errors, ack.command) == (2, 7, 0x08, 0x5)


def test_a_pool_with_a_dangling_reference_is_refused_naming_the_object() -> None:
    good = section_control_pool(sections=2)
    objects = list(good.objects)
    i = next(i for i, o in enumerate(objects) if isinstance(o, ProcessData) and o.ddi == 6)
    bad_dpd = replace(objects[i], presentation_id=4321)
    objects[i] = bad_dpd
    bad = ObjectPool(tuple(objects))
    bin_element = next(o for o in objects if isinstance(o, DeviceElement)
                       and o.element_type == ElementType.BIN)
    port = FakePort()
    server = _server(port, setpoints=constant_setpoints({6: 1}))
    answer = Client(port).connect(bad, 0.0)
    assert answer == pd.ObjectPoolActivateResponse(
        ActivationError.ERRORS_IN_DDOP, bin_element.object_id, bad_dpd.object_id,
        PoolError.UNKNOWN_OBJECT_REFERENCE)
    assert server.events[-1].kind == EventKind.REFUSED
    assert f"DDOP object {bad_dpd.object_id}: presentation object 4321" in \
        server.events[-1].detail
    assert not server.sessions[CLIENT].active
    sent = _run(server, port, 0.1, 1.0)
    assert all(dest != CLIENT for _, _, _, dest in sent)  # no set-points, no triggers
    assert server.store.clients() == []


def test_malformed_pool_bytes_are_refused_with_the_byte_named() -> None:
    port = FakePort()
    server = _server(port)
    client = Client(port)
    client.working_set_master(0.0)
    client.send(pd.ObjectPoolTransfer(section_control_pool().to_bytes()[:-5]), 0.1)
    (answer,) = client.send(pd.ObjectPoolActivate(True), 0.2)
    assert answer.activation_errors == ActivationError.ERRORS_IN_DDOP
    assert "at byte" in server.events[-1].detail


def test_a_pool_whose_device_name_is_not_the_clients_is_refused() -> None:
    port = FakePort()
    server = _server(port)
    answer = Client(port).connect(section_control_pool(name=NAME + 1), 0.0)
    assert answer.activation_errors == ActivationError.ERRORS_IN_DDOP
    assert answer.object_id == 0 and answer.pool_errors == PoolError.ANY_OTHER_ERROR
    assert "NAME" in server.events[-1].detail


def test_activate_without_a_pool_is_refused() -> None:
    port = FakePort()
    _server(port)
    client = Client(port)
    client.working_set_master(0.0)
    assert client.send(pd.ObjectPoolActivate(True), 0.1) == [
        pd.ObjectPoolActivateResponse(ActivationError.ANY_OTHER_ERROR, 0xFFFF, 0xFFFF, 0)]


def test_too_large_a_pool_is_refused_before_the_transfer() -> None:
    port = FakePort()
    server = _server(port, options=ServerOptions(memory_bytes=100))
    client = Client(port)
    client.working_set_master(0.0)
    assert client.send(pd.RequestObjectPoolTransfer(1000), 0.1) == [
        pd.RequestObjectPoolTransferResponse(False)]
    assert client.send(pd.ObjectPoolTransfer(b"x" * 101), 0.2) == [
        pd.ObjectPoolTransferResponse(0x01, 101)]
    refused = [e for e in server.events if e.kind == EventKind.REFUSED]
    assert [e.detail for e in refused] == ["not enough memory: a pool of 1000 bytes, room for 100"]


# --- stored pools: labels, skipped transfers, one label with another pool ---

def test_a_known_pool_is_found_by_its_labels_and_activates_without_a_transfer() -> None:
    pool = section_control_pool(sections=4)
    store = PoolStore()
    port = FakePort()
    _server(port, store=store)
    Client(port).connect(pool, 0.0)

    port2 = FakePort()
    server2 = _server(port2, store=store)
    client = Client(port2)
    client.working_set_master(10.0)
    assert client.send(pd.RequestStructureLabel(), 10.1) == [pd.StructureLabel(b"AGRIHIL")]
    assert client.send(pd.RequestLocalizationLabel(), 10.2) == [
        pd.LocalizationLabel(pool.device.localization_label)]
    assert client.send(pd.RequestStructureLabel(b"OTHERLB"), 10.3) == [pd.StructureLabel()]
    assert client.send(pd.ObjectPoolActivate(True), 10.4) == [pd.ObjectPoolActivateResponse(0)]
    assert server2.sessions[CLIENT].pool == pool


def test_an_unknown_client_gets_no_labels() -> None:
    port = FakePort()
    _server(port)
    client = Client(port)
    client.working_set_master(0.0)
    assert client.send(pd.RequestStructureLabel(), 0.1) == [pd.StructureLabel()]
    assert client.send(pd.RequestLocalizationLabel(), 0.1) == [pd.LocalizationLabel()]


def test_a_different_pool_under_a_stored_structure_label_is_refused() -> None:
    store = PoolStore()
    port = FakePort()
    server = _server(port, store=store)
    Client(port).connect(section_control_pool(sections=4), 0.0)
    Client(port).send(pd.ObjectPoolActivate(False), 0.5)
    answer = Client(port).connect(section_control_pool(sections=5), 1.0)
    assert answer.activation_errors == ActivationError.DIFFERENT_DDOP_SAME_STRUCTURE_LABEL
    assert server.events[-1].kind == EventKind.REFUSED


def test_delete_forgets_the_stored_pool() -> None:
    store = PoolStore()
    port = FakePort()
    _server(port, store=store)
    client = Client(port)
    client.connect(section_control_pool(), 0.0)
    assert client.send(pd.DeleteObjectPool(), 0.5) == [pd.DeleteObjectPoolResponse(True)]
    assert client.send(pd.RequestStructureLabel(), 0.6) == [pd.StructureLabel()]


def test_a_version_3_client_pool_is_parsed_as_version_3() -> None:
    pool = section_control_pool(version=3)
    port = FakePort()
    server = _server(port)
    client = Client(port)
    client.working_set_master(0.0)
    client.send(pd.Version(3), 0.0)
    raw = pool.to_bytes()
    client.send(pd.ObjectPoolTransfer(raw), 0.1)
    assert client.send(pd.ObjectPoolActivate(True), 0.2) == [pd.ObjectPoolActivateResponse(0)]
    assert server.sessions[CLIENT].pool.version == 3


def test_a_pool_in_two_transfers_is_joined() -> None:
    raw = section_control_pool().to_bytes()
    port = FakePort()
    server = _server(port)
    client = Client(port)
    client.working_set_master(0.0)
    client.send(pd.ObjectPoolTransfer(raw[:500]), 0.1)
    client.send(pd.ObjectPoolTransfer(raw[500:]), 0.2)
    assert client.send(pd.ObjectPoolActivate(True), 0.3) == [pd.ObjectPoolActivateResponse(0)]
    assert server.sessions[CLIENT].pool_raw == raw


# --- timeouts and restarts ---

def test_a_silent_client_is_dropped_after_six_seconds() -> None:
    port = FakePort()
    server = _server(port)
    client = Client(port)
    client.connect(section_control_pool(), 0.0)
    _run(server, port, 0.0, 5.9, client_task=False)
    assert CLIENT in server.sessions
    _run(server, port, 6.0, 6.0, client_task=False)
    assert CLIENT not in server.sessions
    assert server.events[-1].kind == EventKind.TIMED_OUT
    # what the client sees next: its process data is refused with a NACK
    port.deliver(pd.PROCESS_DATA_PGN, pd.encode(ElementCommand(Command.VALUE, 0, 141, 1)), 6.5)
    assert [pgn for pgn, *_ in port.take()] == [0xE800]


def test_client_task_messages_keep_a_session_alive() -> None:
    port = FakePort()
    server = _server(port)
    Client(port).connect(section_control_pool(), 0.0)
    _run(server, port, 0.0, 30.0)
    assert server.sessions[CLIENT].active and server.sessions[CLIENT].task_active


def test_a_restart_is_silent_loses_sessions_and_keeps_pools() -> None:
    pool = section_control_pool()
    port = FakePort()
    server = _server(port, setpoints=constant_setpoints({6: 30_000}))
    client = Client(port)
    client.connect(pool, 0.0)
    _run(server, port, 0.0, 4.0)
    server.restart(4.0, down_s=7.0)
    sent = _run(server, port, 4.0, 14.0)
    # silent while down: the client sees the TC status stop for 7 s, then resume
    assert _statuses(sent) == [11.0, 13.0]
    assert all(t >= 11.0 for t, *_ in sent)
    assert server.sessions == {}
    # the client reconnects; its pool is known, so no transfer
    assert client.connect(pool, 14.1, transfer=False) == pd.ObjectPoolActivateResponse(0)
    sent = _run(server, port, 14.2, 14.2)
    assert any(dest == CLIENT and pd.decode(data) == ElementCommand(
        Command.VALUE, next(e for e in pool.elements if e.element_type == ElementType.BIN
                            ).element_number, 6, 30_000) for _, _, data, dest in sent)
    assert EventKind.SERVER_RESTARTED in [e.kind for e in server.events]


def test_trigger_plan_skips_settable_entities_and_missing_methods() -> None:
    pool = section_control_pool(sections=1)
    commands = TriggerPlan(time_interval_ms=500, distance_interval_mm=1000, change_threshold=None,
                           minimum_threshold=0, maximum_threshold=None).commands(pool)
    assert commands, "the sample pool declares time, distance and threshold methods"
    for c in commands:
        dpd = pool.process_data(c.element, c.ddi)
        assert dpd is not None and not dpd.properties & 0x02
        method = {Command.MEASUREMENT_TIME_INTERVAL: TriggerMethod.TIME_INTERVAL,
                  Command.MEASUREMENT_DISTANCE_INTERVAL: TriggerMethod.DISTANCE_INTERVAL,
                  Command.MEASUREMENT_MINIMUM_THRESHOLD: TriggerMethod.THRESHOLD_LIMITS}[c.command]
        assert dpd.trigger_methods & method
    assert {c.command for c in commands} == {Command.MEASUREMENT_TIME_INTERVAL,
                                             Command.MEASUREMENT_DISTANCE_INTERVAL,
                                             Command.MEASUREMENT_MINIMUM_THRESHOLD}


def test_a_language_command_of_the_wrong_length_is_refused() -> None:
    with pytest.raises(ValueError, match="7 bytes, not 8"):
        TaskControllerServer(FakePort(), language_command=b"en12345")


def test_starting_the_task_sends_the_status_at_once_then_every_two_seconds() -> None:
    port = FakePort()
    server = _server(port)
    _run(server, port, 0.0, 1.0, client_task=False)
    server.set_task_active(True)
    sent = _run(server, port, 1.1, 6.0, client_task=False)
    assert _statuses(sent) == [1.1, 3.1, 5.1]
    assert sent[0][2][4] == pd.ServerStatus.TASK_TOTALS_ACTIVE
    server.set_task_active(True)  # no change, no extra status
    server.set_task_active(False)
    sent = _run(server, port, 6.1, 6.3, client_task=False)
    assert _statuses(sent) == [6.1] and sent[0][2][4] == 0


def test_a_changed_status_waits_200_ms_after_the_last_one() -> None:
    port = FakePort()
    server = _server(port)
    server.tick(0.0)
    assert [pgn for pgn, *_ in port.take()] == [0xEA00, pd.PROCESS_DATA_PGN]  # claims, status
    server.set_task_active(True)
    sent = _run(server, port, 0.1, 0.3, client_task=False)
    assert _statuses(sent) == [0.2]


def test_request_default_process_data_goes_to_the_device_element() -> None:
    pool = section_control_pool(sections=1)
    commands = TriggerPlan(request_default_process_data=True).commands(pool)
    assert commands[0] == ElementCommand(Command.REQUEST_VALUE, 0, 0xDFFF)
    assert encode_first(commands[0]) == bytes([0x02, 0x00, 0xFF, 0xDF, 0xFF, 0xFF, 0xFF, 0xFF])


def encode_first(command: ElementCommand) -> bytes:
    return pd.encode(command)


_VALID = [pd.encode(m) for m in (
    pd.RequestVersion(), pd.Version(3), pd.Version(4), pd.RequestStructureLabel(),
    pd.RequestLocalizationLabel(), pd.RequestObjectPoolTransfer(2000),
    pd.ObjectPoolTransfer(section_control_pool(sections=1).to_bytes()),
    pd.ObjectPoolActivate(True), pd.ObjectPoolActivate(False), pd.DeleteObjectPool(),
    ElementCommand(Command.VALUE, 2, 7, 5), ElementCommand(Command.SET_VALUE_AND_ACKNOWLEDGE,
                                                           0, 141, 1),
    pd.ClientTask(True), pd.ProcessDataAcknowledge(1, 7, AckError.NONE, 4))]
_WSM = pd.encode_working_set_master(pd.WorkingSetMaster(1))


@st.composite
def _messages(draw: st.DrawFn) -> list[tuple[int, bytes, int]]:
    """One message (valid, mutated or random), or a whole connection (WSM, pool, activate)."""
    source = draw(st.sampled_from([0x81, 0x82]))
    kind = draw(st.integers(0, 4))
    if kind == 0:
        return [(pd.WORKING_SET_MASTER_PGN, _WSM, source)]
    if kind == 1:
        return [(pd.PROCESS_DATA_PGN, draw(st.sampled_from(_VALID)), source)]
    if kind == 2:
        data = bytearray(draw(st.sampled_from(_VALID)))
        i = draw(st.integers(0, len(data) - 1))
        data[i] = draw(st.integers(0, 255))
        return [(pd.PROCESS_DATA_PGN, bytes(data[:draw(st.integers(0, len(data)))]), source)]
    if kind == 3:
        return [(pd.WORKING_SET_MASTER_PGN, _WSM, source)] + [
            (pd.PROCESS_DATA_PGN, _VALID[i], source) for i in (6, 7)]
    pgn = draw(st.sampled_from([pd.PROCESS_DATA_PGN, pd.WORKING_SET_MASTER_PGN, 0xEA00]))
    return [(pgn, draw(st.binary(max_size=20)), source)]


@settings(max_examples=50, deadline=None, derandomize=True, database=None)
@given(st.lists(_messages(), max_size=30).map(lambda groups: [m for g in groups for m in g]))
def test_any_sequence_of_messages_never_crashes_the_server(
        messages: list[tuple[int, bytes, int]]) -> None:
    port = FakePort()
    server = _server(port, setpoints=constant_setpoints({6: 1, 290: 0x55}))
    for i, (pgn, data, source) in enumerate(messages):
        port.deliver(pgn, data, i * 0.1, source)
        server.tick(i * 0.1)
        for pgn, payload, _, _ in port.take():
            assert len(payload) >= 8 or (pgn, len(payload)) == (0xEA00, 3)
    server.tick(100.0)
    assert server.sessions == {}


def test_every_logged_value_also_goes_to_the_hook() -> None:
    seen: list[tuple[int, int, int]] = []
    port = FakePort()
    server = _server(port, on_value=lambda v: seen.append((v.element, v.ddi, v.value)))
    client = Client(port)
    client.connect(section_control_pool(sections=1), 0.0)
    client.send(ElementCommand(Command.VALUE, 0, ddi.ACTUAL_WORK_STATE, 1), 0.1)
    client.send(ElementCommand(Command.VALUE, 0, 6, 1), 0.2)  # refused: not logged
    assert seen == [(0, ddi.ACTUAL_WORK_STATE, 1)] == [
        (v.element, v.ddi, v.value) for v in server.values]


@pytest.mark.parametrize(("ddi_", "value", "words"), [
    (ddi.SETPOINT_MASS_PER_AREA_RATE, -5, "outside 0 .. 2147483647"),
    (ddi.SETPOINT_WORK_STATE, 4, "outside 0 .. 3"),
    (ddi.SETPOINT_MASS_PER_AREA_RATE, 2**32, "does not fit 32 bits"),
])
def test_a_set_point_outside_its_ddi_range_is_the_rigs_error(ddi_: int, value: int,
                                                            words: str) -> None:
    port = FakePort()
    server = _server(port, setpoints=constant_setpoints({ddi_: value}))
    Client(port).connect(section_control_pool(sections=1), 0.0)
    with pytest.raises(ValueError, match=f"DDI {ddi_}.*{words}|{words}"):
        server.tick(0.1)


def test_a_condensed_state_may_use_all_32_bits() -> None:
    port = FakePort()
    server = _server(port, setpoints=constant_setpoints({290: 0xFFFFFFFF}))
    client = Client(port)
    client.connect(section_control_pool(sections=1), 0.0)
    server.tick(0.1)
    sent = [m for m in client.replies() if isinstance(m, ElementCommand) and m.ddi == 290]
    assert [m.unsigned for m in sent] == [0xFFFFFFFF]


def test_late_ticks_do_not_stretch_the_status_period() -> None:
    port = FakePort()
    server = _server(port)
    times = [0.0, 2.013, 4.013, 6.005, 8.0, 9.999, 10.0]
    sent = []
    for t in times:
        server.tick(t)
        sent += [t for _, data, _, _ in port.take() if data[0] == 0xFE]
    assert sent == [0.0, 2.013, 4.013, 6.005, 8.0, 10.0]


def test_the_pool_store_is_bounded_as_a_tcs_memory_is() -> None:
    from hil.isobus.tc.store import MAX_CLIENTS, MAX_POOLS_PER_CLIENT

    store = PoolStore()
    pool = section_control_pool(sections=1)
    for name in range(MAX_CLIENTS + 10):            # peers claiming NAME after NAME
        store.put(name, pool, pool.to_bytes())
    assert len(store.clients()) == MAX_CLIENTS and store.clients()[0] == 10
    for k in range(MAX_POOLS_PER_CLIENT + 3):       # one client, label after label
        labelled = section_control_pool(sections=1, structure_label=f"L{k}".encode())
        store.put(5, labelled, labelled.to_bytes())
    assert store.by_structure(5, b"L0     ") is None
    assert store.latest(5).structure_label == f"L{MAX_POOLS_PER_CLIENT + 2}".encode().ljust(7)
    assert len(store._pools[5]) == MAX_POOLS_PER_CLIENT
