"""The TC client (hil.isobus.tc_client) against the rig's TC server, each on its own network,
over a virtual wire in virtual time: connection with the pool over TP, set-points through the
callback, measurement triggers at the right times, a refused pool, a TC restart, a TC lost."""

from __future__ import annotations

from itertools import pairwise

import pytest

from hil.isobus import ddi
from hil.isobus import process_data as pd
from hil.isobus.ddop import ElementType, ObjectPool, ProcessData
from hil.isobus.ddop.samples import section_control_pool
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.process_data import AckError, Command, ElementCommand
from hil.isobus.tc import EventKind, TaskControllerServer, TriggerPlan, constant_setpoints
from hil.isobus.tc.store import PoolStore
from hil.isobus.tc_client import ClientState, TaskControllerClient
from hil.isobus.wire import VirtualWire

TC_NAME = IsobusName(identity_number=2, manufacturer_code=100, function=130, device_class=0)
IMPLEMENT_NAME = IsobusName(identity_number=7, manufacturer_code=200, function=130,
                            device_class=5)
RATE = 25_000


class Implement:
    """What the implement application does with the client: keeps set-points, gives values."""

    def __init__(self) -> None:
        self.setpoints: list[tuple[float, int, int, int]] = []
        self.values: dict[tuple[int, int], int] = {}
        self.connection: list[tuple[bool, float]] = []
        self.distance_mm = 0.0
        self.refuse_setpoint: AckError | None = None

    def on_setpoint(self, element: int, ddi_: int, value: int, t: float) -> AckError | None:
        self.setpoints.append((t, element, ddi_, value))
        if self.refuse_setpoint:
            return self.refuse_setpoint
        return None

    def read_value(self, element: int, ddi_: int, t: float) -> int | None:
        return self.values.get((element, ddi_), 0)

    def on_connection(self, connected: bool, t: float) -> None:
        self.connection.append((connected, t))


class Bench:
    def __init__(self, pool: ObjectPool, *, triggers: TriggerPlan | None = None,
                 store: PoolStore | None = None, speed_mm_s: float = 0.0,
                 tc_start_s: float = 0.0) -> None:
        self.rig = IsobusNetwork(name="rig", start_s=tc_start_s)
        self.dut = IsobusNetwork(name="dut")
        tc_port = self.rig.add(TC_NAME, 0xF7, "TC")
        self.server = TaskControllerServer(
            tc_port, store=store, triggers=triggers or TriggerPlan(),
            setpoints=constant_setpoints({ddi.SETPOINT_MASS_PER_AREA_RATE: RATE}))
        tc_port.run(self.server)
        self.app = Implement()
        self.speed_mm_s = speed_mm_s
        port = self.dut.add(IMPLEMENT_NAME, 0x81, "implement")
        self.client = TaskControllerClient(
            port, pool, on_setpoint=self.app.on_setpoint, read_value=self.app.read_value,
            distance_mm=lambda t: t * self.speed_mm_s, on_connection=self.app.on_connection)
        port.run(self.client)
        self.wire = VirtualWire([self.rig, self.dut])

    def run(self, until_s: float) -> None:
        self.wire.run_until(until_s)

    def client_frames(self, command: int) -> list[tuple[float, bytes]]:
        """Process data the client sent with ``command`` (single frames only)."""
        out = []
        for f in self.wire.frames:
            cid = f.frame.arbitration_id
            if (cid >> 8) & 0x3FF00 == pd.PROCESS_DATA_PGN and cid & 0xFF == 0x81 \
                    and f.frame.data[0] & 0x0F == command:
                out.append((f.time_s, bytes(f.frame.data)))
        return out


def _pool() -> ObjectPool:
    return section_control_pool(sections=4, name=IMPLEMENT_NAME.value)


def _element(pool: ObjectPool, kind: ElementType) -> int:
    return next(e.element_number for e in pool.elements if e.element_type == kind)


def test_the_client_connects_transferring_its_pool_over_tp_and_gets_set_points() -> None:
    pool = _pool()
    bench = Bench(pool)
    bench.run(10.0)

    client = bench.client
    assert client.state is ClientState.CONNECTED, client.events
    assert client.transfers == 1 and client.connections == 1
    session = bench.server.sessions[0x81]
    assert session.pool == pool and session.version == 4
    tp = [f for f in bench.wire.frames if (f.frame.arbitration_id >> 8) & 0x3FF00 == 0xEC00]
    assert tp, "the pool travels by TP connection management"
    # the order of the standard: WSM, client task, version, language, labels, transfer, activate
    kinds = [e.detail for e in client.events if e.kind == "state"]
    assert kinds == [s.value for s in (
        ClientState.WAIT_STATUS, ClientState.WAIT_VERSION, ClientState.WAIT_LANGUAGE,
        ClientState.WAIT_STRUCTURE_LABEL, ClientState.WAIT_TRANSFER_PERMISSION,
        ClientState.WAIT_TRANSFER_RESPONSE, ClientState.WAIT_ACTIVATION,
        ClientState.CONNECTED)]
    assert client.language is not None and client.language[:2] == b"en"
    # the set-point came through the callback, on the product bin
    product = _element(pool, ElementType.BIN)
    assert (product, ddi.SETPOINT_MASS_PER_AREA_RATE, RATE) in [s[1:] for s in
                                                               bench.app.setpoints]
    connected_at = next(e.time_s for e in client.events if e.detail == "connected")
    assert bench.app.connection == [(True, connected_at)] and connected_at < 1.0
    # the client task message every 2 s from the working-set master on
    tasks = [t for t, _ in bench.client_frames(Command.CLIENT_TASK)]
    gaps = [b - a for a, b in pairwise(tasks)]
    assert len(tasks) >= 4 and all(abs(g - 2.0) < 0.02 for g in gaps), tasks


def test_a_pool_beyond_1785_bytes_travels_by_etp() -> None:
    pool = section_control_pool(sections=16, name=IMPLEMENT_NAME.value)
    assert len(pool.to_bytes()) > 1785
    bench = Bench(pool)
    bench.run(6.0)
    assert bench.client.connected and bench.client.transfers == 1
    assert bench.server.sessions[0x81].pool == pool
    etp = [f for f in bench.wire.frames if (f.frame.arbitration_id >> 8) & 0x3FF00 == 0xC800]
    tp = [f for f in bench.wire.frames if (f.frame.arbitration_id >> 8) & 0x3FF00 == 0xEC00]
    assert etp and not tp, "ETP connection management, no TP"


def test_a_set_point_the_implement_refuses_is_acknowledged_with_its_errors() -> None:
    pool = _pool()
    bench = Bench(pool)
    bench.app.refuse_setpoint = AckError.VALUE_OUT_OF_OPERATIONAL_RANGE
    bench.run(5.0)
    acks = [a for a in bench.server.acknowledgements
            if a.ddi == ddi.SETPOINT_MASS_PER_AREA_RATE]
    assert acks and acks[0].errors == AckError.VALUE_OUT_OF_OPERATIONAL_RANGE
    assert acks[0].command == Command.VALUE


def test_value_commands_on_what_the_pool_does_not_have_are_acknowledged_as_errors() -> None:
    pool = _pool()
    bench = Bench(pool, triggers=TriggerPlan(time_interval_ms=None, change_threshold=None))
    bench.run(4.0)
    tc = bench.rig.functions[0]
    product = _element(pool, ElementType.BIN)
    sent = [ElementCommand(Command.VALUE, 99, ddi.SETPOINT_MASS_PER_AREA_RATE, 1),
            ElementCommand(Command.VALUE, product, ddi.SETPOINT_SEEDING_DEPTH, 1),
            ElementCommand(Command.VALUE, product, ddi.ACTUAL_MASS_PER_AREA_RATE, 1),
            ElementCommand(Command.SET_VALUE_AND_ACKNOWLEDGE, product,
                           ddi.SETPOINT_MASS_PER_AREA_RATE, 7),
            ElementCommand(Command.REQUEST_VALUE, product, ddi.ACTUAL_MASS_PER_AREA_RATE)]
    bench.app.values[(product, ddi.ACTUAL_MASS_PER_AREA_RATE)] = 23_456
    for m in sent:
        tc.send(pd.PROCESS_DATA_PGN, pd.encode(m), 0x81)
    before = len(bench.server.values)
    bench.run(4.5)
    errors = [(a.element, a.ddi, a.errors) for a in bench.server.acknowledgements]
    assert errors == [(99, ddi.SETPOINT_MASS_PER_AREA_RATE, AckError.INVALID_ELEMENT_NUMBER),
                      (product, ddi.SETPOINT_SEEDING_DEPTH,
                       AckError.DDI_NOT_SUPPORTED_BY_ELEMENT),
                      (product, ddi.ACTUAL_MASS_PER_AREA_RATE, AckError.NOT_SETTABLE),
                      (product, ddi.SETPOINT_MASS_PER_AREA_RATE, AckError.NONE)]
    assert bench.app.setpoints[-1][1:] == (product, ddi.SETPOINT_MASS_PER_AREA_RATE, 7)
    answered = [v for v in bench.server.values[before:]
                if v.ddi == ddi.ACTUAL_MASS_PER_AREA_RATE]
    assert [v.value for v in answered] == [23_456]


def test_time_interval_triggers_send_values_at_their_interval() -> None:
    pool = _pool()
    bench = Bench(pool, triggers=TriggerPlan(time_interval_ms=500, change_threshold=None))
    product = _element(pool, ElementType.BIN)
    bench.app.values[(product, ddi.ACTUAL_MASS_PER_AREA_RATE)] = 24_000
    bench.run(8.0)
    times = [v.time_s for v in bench.server.values if v.element == product
             and v.ddi == ddi.ACTUAL_MASS_PER_AREA_RATE]
    assert len(times) >= 10
    gaps = [b - a for a, b in pairwise(times)]
    assert all(abs(g - 0.5) < 0.011 for g in gaps), gaps
    assert bench.client.triggers()[(product, ddi.ACTUAL_MASS_PER_AREA_RATE)] == {
        "time_ms": 500}


def test_distance_interval_triggers_send_a_value_every_interval_of_travel() -> None:
    pool = _pool()
    # 2 m/s, a value every 5 m: every 2.5 s
    bench = Bench(pool, triggers=TriggerPlan(time_interval_ms=None, change_threshold=None,
                                             distance_interval_mm=5000), speed_mm_s=2000.0)
    product = _element(pool, ElementType.BIN)
    bench.run(14.0)
    times = [v.time_s for v in bench.server.values if v.element == product
             and v.ddi == ddi.ACTUAL_MASS_PER_AREA_RATE]
    assert len(times) >= 4
    gaps = [b - a for a, b in pairwise(times)]
    assert all(abs(g - 2.5) < 0.02 for g in gaps), gaps


def test_change_triggers_send_when_the_value_moves_by_the_threshold() -> None:
    pool = _pool()
    bench = Bench(pool, triggers=TriggerPlan(time_interval_ms=None, change_threshold=1000))
    product = _element(pool, ElementType.BIN)
    key = (product, ddi.ACTUAL_MASS_PER_AREA_RATE)
    bench.app.values[key] = 10_000
    bench.run(5.0)

    def sent() -> list[int]:
        return [v.value for v in bench.server.values if (v.element, v.ddi) == key]

    assert sent() == [10_000]              # the first reading once the trigger is set
    for value, expected in ((10_900, [10_000]), (11_000, [10_000, 11_000]),
                            (10_100, [10_000, 11_000]), (9_900, [10_000, 11_000, 9_900])):
        bench.app.values[key] = value
        bench.run(bench.wire.now + 1.0)
        assert sent() == expected, (value, sent())
    times = [v.time_s for v in bench.server.values if (v.element, v.ddi) == key]
    assert times[1] == pytest.approx(6.0, abs=0.011)   # within one 10 ms poll of the change


def test_within_threshold_triggers_send_when_the_value_enters_the_window() -> None:
    # minimum and maximum *within* threshold: report while above the minimum and below the
    # maximum, once per entry (AgIsoStack++ reports leaving the window instead)
    pool = _pool()
    bench = Bench(pool, triggers=TriggerPlan(time_interval_ms=None, change_threshold=None,
                                             minimum_threshold=20_000,
                                             maximum_threshold=30_000))
    product = _element(pool, ElementType.BIN)
    key = (product, ddi.ACTUAL_MASS_PER_AREA_RATE)
    bench.app.values[key] = 10_000
    bench.run(5.0)
    assert bench.client.triggers()[key] == {"minimum": 20_000, "maximum": 30_000}

    def sent() -> list[int]:
        return [v.value for v in bench.server.values if (v.element, v.ddi) == key]

    assert sent() == []                    # below the window
    for value, expected in ((25_000, [25_000]), (27_000, [25_000]), (35_000, [25_000]),
                            (15_000, [25_000]), (21_000, [25_000, 21_000])):
        bench.app.values[key] = value
        bench.run(bench.wire.now + 1.0)
        assert sent() == expected, (value, sent())


def test_a_trigger_the_dpd_does_not_declare_is_refused() -> None:
    pool = _pool()
    bench = Bench(pool)
    bench.run(4.0)
    boom = _element(pool, ElementType.FUNCTION)
    # the working width DPD declares on change only
    dpd = pool.process_data(boom, ddi.ACTUAL_WORKING_WIDTH)
    assert isinstance(dpd, ProcessData)
    bench.rig.functions[0].send(pd.PROCESS_DATA_PGN, pd.encode(ElementCommand(
        Command.MEASUREMENT_TIME_INTERVAL, boom, ddi.ACTUAL_WORKING_WIDTH, 1000)), 0x81)
    bench.run(4.5)
    assert [(a.ddi, a.errors) for a in bench.server.acknowledgements] == [
        (ddi.ACTUAL_WORKING_WIDTH, AckError.TRIGGER_METHOD_NOT_SUPPORTED)]
    assert "time_ms" not in bench.client.triggers()[(boom, ddi.ACTUAL_WORKING_WIDTH)]


def test_a_known_pool_is_activated_without_a_transfer() -> None:
    store = PoolStore()
    first = Bench(_pool(), store=store)
    first.run(5.0)
    assert first.client.transfers == 1
    second = Bench(_pool(), store=store)
    second.run(5.0)
    assert second.client.state is ClientState.CONNECTED
    assert second.client.transfers == 0
    assert any(e.kind == "pool known" for e in second.client.events)


def test_a_refused_pool_reports_the_error_codes_and_the_client_does_not_loop() -> None:
    # a pool whose device NAME is not the client's: the TC refuses it at activation
    pool = section_control_pool(sections=4, name=IMPLEMENT_NAME.value + 1)
    bench = Bench(pool)
    bench.run(30.0)
    client = bench.client
    assert client.state is ClientState.REFUSED
    refusal = client.refusal
    assert refusal is not None
    assert refusal.activation_errors == 0x01 and refusal.object_id == pool.device.object_id
    assert "activation errors 0x01 (errors_in_ddop)" in refusal.reason
    assert f"object {pool.device.object_id}" in refusal.reason
    # one attempt, then quiet: no second transfer, no activation again, no client task
    assert client.transfers == 1
    assert [e.kind for e in bench.server.events].count(EventKind.REFUSED) == 1
    last = max(t for t, _ in bench.client_frames(Command.CLIENT_TASK))
    assert last < refusal.time_s + 0.01
    # a corrected pool gets in on retry
    client.retry(_pool())
    bench.run(40.0)
    assert client.state is ClientState.CONNECTED and client.refusal is None


def test_a_tc_restart_shorter_than_the_timeout_is_noticed_from_its_nack() -> None:
    pool = _pool()
    bench = Bench(pool, triggers=TriggerPlan(time_interval_ms=500, change_threshold=None))
    bench.run(5.0)
    assert bench.client.connected
    bench.server.restart(5.0, down_s=1.0)
    bench.run(12.0)
    client = bench.client
    assert client.connected
    assert client.connections == 2 and client.transfers == 1, "the TC kept the pool"
    restart = next(e for e in client.events if e.kind == "restart")
    assert "NACK" in restart.detail and 6.0 <= restart.time_s < 7.0
    assert [c for c, _ in bench.app.connection] == [True, False, True]
    # set-points flow again after the reconnection
    assert any(t > restart.time_s for t, *_ in bench.app.setpoints)


def test_a_tc_lost_for_six_seconds_is_dropped_and_reconnected_when_it_returns() -> None:
    pool = _pool()
    bench = Bench(pool)
    bench.run(5.0)
    last_status = max(f.time_s for f in bench.wire.frames
                      if f.frame.arbitration_id & 0xFF == 0xF7
                      and f.frame.data[0] == 0xFE)
    bench.server.restart(5.0, down_s=10.0)
    bench.run(14.0)
    client = bench.client
    lost = next(e for e in client.events if e.kind == "lost")
    assert lost.time_s == pytest.approx(last_status + 6.0, abs=0.011)
    assert client.state is ClientState.WAIT_STATUS
    assert bench.app.connection == [(True, bench.app.connection[0][1]), (False, lost.time_s)]
    # no client task while no TC is there
    assert not [t for t, _ in bench.client_frames(Command.CLIENT_TASK) if t > lost.time_s]
    bench.run(20.0)
    assert client.connected and client.connections == 2


def test_the_client_waits_for_a_tc_status_before_it_sends_anything() -> None:
    bench = Bench(_pool(), tc_start_s=3.0)
    bench.run(2.9)
    assert bench.client.state is ClientState.WAIT_STATUS
    sent = [f for f in bench.wire.frames if f.frame.arbitration_id & 0xFF == 0x81
            and (f.frame.arbitration_id >> 8) & 0x3FF00 != 0xEE00]
    assert sent == [], "only its address claim before the TC's status"
    bench.run(8.0)
    assert bench.client.connected
