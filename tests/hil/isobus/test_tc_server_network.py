"""The TC server through the real network layer: a scripted client on a second network, its DDOP
over TP, in virtual time (``hil.isobus.network`` + ``hil.isobus.wire``)."""

from __future__ import annotations

from hil.isobus import ddi
from hil.isobus import process_data as pd
from hil.isobus.ddop import ElementType, ObjectPool
from hil.isobus.ddop.samples import section_control_pool
from hil.isobus.name import IsobusName
from hil.isobus.network import InternalControlFunction, IsobusNetwork
from hil.isobus.port import GLOBAL_ADDRESS, Received
from hil.isobus.process_data import Command, ElementCommand
from hil.isobus.tc import EventKind, TaskControllerServer, constant_setpoints
from hil.isobus.wire import VirtualWire

TC_NAME = IsobusName(identity_number=2, manufacturer_code=100, function=130, device_class=0)
IMPLEMENT_NAME = IsobusName(identity_number=7, manufacturer_code=200, function=130,
                            device_class=5)


class ScriptedClient:
    """A TC client in the order AgIsoStack++'s client takes: status, working-set master,
    its request for the TC's version, the TC's version, then waiting for the TC's request for
    its own (a request at any other time is what AgIsoStack++ warns of, "Server requested
    version information at a strange time": kept in :attr:`strange`), labels, transfer,
    activate; then an actual rate every 0.5 s."""

    def __init__(self, port: InternalControlFunction, pool: ObjectPool) -> None:
        self.port = port
        self.pool = pool
        self.tc: int | None = None
        self.state = "wait status"
        self.connected_s: float | None = None
        self.setpoints: list[tuple[float, ElementCommand]] = []
        self.triggers: list[ElementCommand] = []
        self.status_seen: list[float] = []
        self.strange: list[float] = []
        self._next_task_s = 0.0
        self._next_value_s = 0.0
        port.subscribe(pd.PROCESS_DATA_PGN, self._on_process_data)

    def _send(self, message: pd.ProcessDataMessage) -> None:
        assert self.tc is not None
        self.port.send(pd.PROCESS_DATA_PGN, pd.encode(message), self.tc, 5)

    def _on_process_data(self, msg: Received) -> None:
        m = pd.decode(msg.data)
        if isinstance(m, pd.TaskControllerStatus):
            self.status_seen.append(msg.time_s)
            if self.tc is None:
                self.tc = msg.source
            return
        if msg.destination != self.port.address:
            return
        match m:
            case pd.RequestVersion():
                if self.state != "wait version request":
                    self.strange.append(msg.time_s)
                    return
                self._send(pd.Version(4, pd.VersionOption.IMPLEMENT_SECTION_CONTROL, 1, 4, 1))
                self.state = "wait structure label"
                self._send(pd.RequestStructureLabel())
            case pd.Version() if self.state == "wait version":
                self.state = "wait version request"
            case pd.StructureLabel():
                if m.label == self.pool.device.structure_label:
                    self.state = "wait localization label"
                    self._send(pd.RequestLocalizationLabel())
                else:
                    self._request_transfer()
            case pd.LocalizationLabel():
                if m.label == self.pool.device.localization_label:
                    self._activate()
                else:
                    self._request_transfer()
            case pd.RequestObjectPoolTransferResponse(enough_memory=True):
                self.state = "wait transfer response"
                self._send(pd.ObjectPoolTransfer(self.pool.to_bytes()))
            case pd.ObjectPoolTransferResponse(errors=0):
                self._activate()
            case pd.ObjectPoolActivateResponse(activation_errors=0):
                self.state = "connected"
                self.connected_s = msg.time_s
            case ElementCommand(command=Command.VALUE):
                self.setpoints.append((msg.time_s, m))
            case ElementCommand():
                self.triggers.append(m)

    def _request_transfer(self) -> None:
        self.state = "wait transfer request response"
        self._send(pd.RequestObjectPoolTransfer(len(self.pool.to_bytes())))

    def _activate(self) -> None:
        self.state = "wait activate response"
        self._send(pd.ObjectPoolActivate(True))

    def tick(self, now_s: float) -> None:
        if self.tc is None or self.port.address is None:
            return
        if self.state == "wait status":
            self.state = "wait version"
            self.port.send(pd.WORKING_SET_MASTER_PGN,
                           pd.encode_working_set_master(pd.WorkingSetMaster(1)), GLOBAL_ADDRESS,
                           7)
            self._send(pd.RequestVersion())
        if now_s >= self._next_task_s:
            self._send(pd.ClientTask(False))
            self._next_task_s = now_s + 2.0
        if self.state == "connected" and now_s >= self._next_value_s:
            product = next(e for e in self.pool.elements if e.element_type == ElementType.BIN)
            self._send(ElementCommand(Command.VALUE, product.element_number,
                                      ddi.ACTUAL_MASS_PER_AREA_RATE, 24_000))
            self._next_value_s = now_s + 0.5


def _bench(pool: ObjectPool) -> tuple[VirtualWire, TaskControllerServer, ScriptedClient,
                                      IsobusNetwork]:
    rig, dut = IsobusNetwork(name="rig"), IsobusNetwork(name="dut")
    tc_port = rig.add(TC_NAME, 0xF7, "TC")
    server = TaskControllerServer(tc_port, setpoints=constant_setpoints(
        {ddi.SETPOINT_MASS_PER_AREA_RATE: 25_000}))
    tc_port.run(server)
    client_port = dut.add(IMPLEMENT_NAME, 0x81, "implement")
    client = ScriptedClient(client_port, pool)
    client_port.run(client)
    return VirtualWire([rig, dut]), server, client, rig


def test_a_client_connects_over_the_network_with_its_pool_over_tp() -> None:
    pool = section_control_pool(sections=4, name=IMPLEMENT_NAME.value)
    assert len(pool.to_bytes()) > 8 * 7  # more than one frame: TP carries it
    wire, server, client, _ = _bench(pool)
    wire.run_until(10.0)

    assert client.state == "connected", (client.state, [str(e) for e in server.events])
    assert client.connected_s is not None and client.connected_s < 2.0
    assert client.strange == [], "the TC asked the client's version out of turn"
    tp_frames = [f for f in wire.frames if (f.frame.arbitration_id >> 8) & 0x3FF00 == 0xEC00]
    assert tp_frames, "the DDOP must travel by TP connection management"
    session = server.sessions[0x81]
    assert session.name == IMPLEMENT_NAME.value and session.pool == pool
    # set-points arrived at the client; values flowed back and were logged
    product = next(e for e in pool.elements if e.element_type == ElementType.BIN)
    assert client.setpoints[0][1] == ElementCommand(Command.VALUE, product.element_number,
                                                    ddi.SETPOINT_MASS_PER_AREA_RATE, 25_000)
    assert client.triggers, "measurement triggers were sent"
    logged = [v for v in server.values if v.ddi == ddi.ACTUAL_MASS_PER_AREA_RATE]
    assert len(logged) >= 10 and all(v.value == 24_000 for v in logged)
    # the TC's status went out every 2 s from its claim on
    gaps = [b - a for a, b in zip(client.status_seen, client.status_seen[1:], strict=False)]
    assert gaps and all(abs(g - 2.0) < 0.02 for g in gaps)


def test_a_restart_over_the_network_makes_the_client_reconnect_without_a_transfer() -> None:
    pool = section_control_pool(sections=4, name=IMPLEMENT_NAME.value)
    wire, server, client, _ = _bench(pool)
    wire.run_until(5.0)
    assert client.state == "connected"
    server.restart(5.0, down_s=7.0)
    wire.run_until(12.5)
    # the client saw the status stop; a client that notices (6 s) starts over
    assert max(b - a for a, b in zip(client.status_seen, client.status_seen[1:],
                                     strict=False)) > 6.0
    client.state, client.tc = "wait status", None
    wire.run_until(20.0)
    assert client.state == "connected"
    kinds = [e.kind for e in server.events]
    restart = kinds.index(EventKind.SERVER_RESTARTED)
    assert EventKind.ACTIVATED in kinds[restart:]
    assert EventKind.POOL_TRANSFERRED not in kinds[restart:]
