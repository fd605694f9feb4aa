"""Any message a working set sends is answered or refused: the VT never raises on one."""

from __future__ import annotations

from collections import defaultdict

from hypothesis import given, settings
from hypothesis import strategies as st

from hil.isobus.port import GLOBAL_ADDRESS, Handler, Received
from hil.isobus.vt.messages import ECU_TO_VT_PGN, Function, KeyActivation, pad
from hil.isobus.vt.server import VirtualTerminalServer

from .pools import IDS, implement_pool

VT, CLIENT = 0x26, 0x84


class FakePort:
    def __init__(self) -> None:
        self.sent: list[tuple[int, bytes, int]] = []
        self.handlers: dict[int, list[Handler]] = defaultdict(list)

    @property
    def address(self) -> int:
        return VT

    def send(self, pgn: int, data: bytes, destination: int = GLOBAL_ADDRESS,
             priority: int = 6) -> None:
        self.sent.append((pgn, bytes(data), destination))

    def subscribe(self, pgn: int, handler: Handler) -> None:
        self.handlers[pgn].append(handler)

    def name_of(self, address: int) -> int | None:
        return 0xA00C80000AE00002 if address == CLIENT else None

    def deliver(self, data: bytes, t: float) -> None:
        for handler in self.handlers[ECU_TO_VT_PGN]:
            handler(Received(ECU_TO_VT_PGN, bytes(data), CLIENT, VT, t))


def connected() -> tuple[VirtualTerminalServer, FakePort]:
    port = FakePort()
    vt = VirtualTerminalServer(port)     # type: ignore[arg-type]
    vt.tick(0.0)
    port.deliver(pad([Function.WORKING_SET_MAINTENANCE, 1, 4]), 0.1)
    port.deliver(pad([Function.GET_MEMORY, 0xFF, 0, 0x10, 0, 0]), 0.1)
    port.deliver(bytes([Function.OBJECT_POOL_TRANSFER]) + implement_pool().to_bytes(), 0.2)
    port.deliver(pad([Function.END_OF_OBJECT_POOL]), 0.3)
    assert vt.sessions[CLIENT].active
    return vt, port


functions = st.sampled_from([int(f) for f in Function] + [0x90, 0xB8, 0xBA, 0x42])
messages = st.builds(lambda f, rest: bytes([f]) + rest, functions, st.binary(max_size=40))


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(st.lists(messages, max_size=12))
def test_any_message_sequence_is_answered_or_refused(sequence: list[bytes]) -> None:
    vt, port = connected()
    t = 0.5
    for data in sequence:
        port.deliver(data, t)
        vt.tick(t)
        t += 0.05
    # whatever came, the VT still answers a well-formed command
    port.sent.clear()
    port.deliver(pad([Function.GET_NUMBER_OF_SOFT_KEYS]), t)
    assert port.sent and port.sent[-1][1][0] == Function.GET_NUMBER_OF_SOFT_KEYS
    ws = vt.sessions.get(CLIENT)
    if ws is not None and ws.pool is not None and ws.is_shown(IDS.key_master):
        vt.key_event(IDS.key_master, KeyActivation.PRESSED, t)
        assert port.sent[-1][1][:4] == bytes([0x00, 0x01]) + IDS.key_master.to_bytes(2,
                                                                                     "little")
