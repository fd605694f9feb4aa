"""A VT client (ISO 11783-6): the implement's side of the Virtual Terminal.

:class:`VtClient` runs on an :class:`~hil.isobus.port.IsobusPort` like the rig's applications
(no thread, no clock). Its connection follows AgIsoStack++'s client
(``isobus_virtual_terminal_client.cpp`` at 509a920), which is the order the standard gives:

1. wait for a VT status message and bind to that VT;
2. send the working set master message (PGN 0xFE0D) and the working set maintenance message
   (initiating bit set first, then every second);
3. get memory with the pool's size (refused: the client stops), get number of soft keys, get
   text font data, get hardware;
4. with a version label: get versions; when the VT has the label, load version; connected
   when the load succeeds;
5. otherwise upload the pool: each object pool transfer (one or several) as one parameter
   group, the next only once the network layer has sent the previous, then end of object
   pool; a refusal keeps the response's error codes in :attr:`VtClient.refusal` and stops;
   with a label, store version; connected.

Connected, it sends its commands one at a time (the next after the VT's response to the one
before) and hands the operator's messages (soft key and button activations, numeric and
string values) to its hooks. It starts over from step 1 when the VT status stops for 3 s.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from hil.isobus.port import GLOBAL_ADDRESS, IsobusPort, Received
from hil.isobus.vt.messages import (
    ECU_TO_VT_PGN,
    LABEL_LENGTH,
    VT_TO_ECU_PGN,
    WORKING_SET_MASTER_PGN,
    Function,
    KeyActivation,
    get16,
    get32,
    pad,
    u16,
    u32,
)

VT_STATUS_TIMEOUT_S = 3.0
MAINTENANCE_PERIOD_S = 1.0
RESPONSE_TIMEOUT_S = 3.0
PRIORITY = 5


@dataclass(frozen=True)
class KeyEvent:
    """A soft key or button activation the VT reported."""

    time_s: float
    object_id: int
    parent_id: int
    key_code: int
    activation: KeyActivation
    button: bool


@dataclass(frozen=True)
class Refusal:
    """Why the VT refused the pool (end of object pool response or get memory)."""

    error_codes: int
    parent_id: int
    object_id: int
    pool_error_codes: int
    reason: str


@dataclass
class _Command:
    data: bytes
    sent_s: float | None = None


#: the bytes a VT-to-ECU message needs for what the client reads of it (a shorter one from a
#: broken or hostile VT is ignored rather than read past its end)
_NEEDED: dict[int, int] = {
    Function.VT_STATUS: 4, Function.GET_MEMORY: 3, Function.GET_VERSIONS_RESPONSE: 2,
    Function.LOAD_VERSION: 6, Function.END_OF_OBJECT_POOL: 7, Function.SOFT_KEY_ACTIVATION: 7,
    Function.BUTTON_ACTIVATION: 7, Function.VT_CHANGE_NUMERIC_VALUE: 8,
    Function.VT_CHANGE_STRING_VALUE: 4,
}


@dataclass
class VtClient:
    """A working set's VT client (see the module docstring).

    Parameters
    ----------
    port : IsobusPort
        The implement's control function.
    transfers : sequence of bytes
        The pool, in one or several object pool transfers (each without the 0x11 byte).
    version_label : bytes or None
        7-byte label to store and load the pool under (``None``: always upload).
    vt_version : int
        The VT version the client reports in its maintenance message.
    transport_idle : callable, optional
        True when the network layer has sent everything queued (the next transfer, or the
        end of object pool, waits for it); by default the port's network is asked.
    """

    port: IsobusPort
    transfers: Sequence[bytes]
    version_label: bytes | None = None
    vt_version: int = 4
    transport_idle: Callable[[], bool] | None = None
    state: str = "wait status"
    vt: int | None = None
    vt_status_s: float | None = None
    connected_s: float | None = None
    refusal: Refusal | None = None
    loaded: bool = False
    keys: list[KeyEvent] = field(default_factory=list)
    numbers: list[tuple[float, int, int]] = field(default_factory=list)
    strings: list[tuple[float, int, str]] = field(default_factory=list)
    responses: list[tuple[float, bytes]] = field(default_factory=list)
    on_key: Callable[[KeyEvent], None] | None = None
    on_number: Callable[[int, int, float], None] | None = None
    on_string: Callable[[int, str, float], None] | None = None
    on_connected: Callable[[float], None] | None = None
    vt_data_mask: int = 0xFFFF
    _next_maintenance_s: float = math.inf
    _state_s: float = 0.0
    _to_send: deque[bytes] = field(default_factory=deque)
    _commands: deque[_Command] = field(default_factory=deque)
    _now: float = 0.0

    def __post_init__(self) -> None:
        if self.version_label is not None:
            self.version_label = (bytes(self.version_label) + b" " * LABEL_LENGTH)[:LABEL_LENGTH]
        self.port.subscribe(VT_TO_ECU_PGN, self._on_vt)

    # -- the implement's commands ----------------------------------------------------------------

    def command(self, data: bytes) -> None:
        """Queue a command (sent once connected, one at a time)."""
        self._commands.append(_Command(bytes(data)))

    def change_numeric_value(self, object_id: int, value: int) -> None:
        """Change numeric value (0xA8)."""
        self.command(bytes([Function.CHANGE_NUMERIC_VALUE]) + u16(object_id) + b"\xff"
                     + u32(value))

    def change_active_mask(self, working_set_id: int, mask_id: int) -> None:
        """Change active mask (0xAD)."""
        self.command(pad(bytes([Function.CHANGE_ACTIVE_MASK]) + u16(working_set_id)
                         + u16(mask_id)))

    def change_string_value(self, object_id: int, text: bytes) -> None:
        """Change string value (0xB3)."""
        self.command(pad(bytes([Function.CHANGE_STRING_VALUE]) + u16(object_id)
                         + u16(len(text)) + text))

    def hide_show(self, object_id: int, show: bool) -> None:
        """Hide/show object (0xA0)."""
        self.command(pad(bytes([Function.HIDE_SHOW]) + u16(object_id) + bytes([int(show)])))

    # -- timers ----------------------------------------------------------------------------------

    def next_due(self, now_s: float) -> float:
        """When the client has something to do."""
        due = self._next_maintenance_s
        if self._to_send or (self.state == "connected" and self._commands
                             and self._commands[0].sent_s is None):
            due = now_s
        if self.vt_status_s is not None:
            due = min(due, self.vt_status_s + VT_STATUS_TIMEOUT_S)
        if self.state.startswith("wait ") and self.state != "wait status":
            due = min(due, self._state_s + RESPONSE_TIMEOUT_S)
        if self.state in ("uploading", "end of pool"):
            due = min(due, now_s + 0.01)
        return max(due, now_s)

    def tick(self, now_s: float) -> None:
        """Advance to ``now_s``."""
        self._now = now_s
        if self.vt_status_s is not None and now_s - self.vt_status_s >= VT_STATUS_TIMEOUT_S:
            self._restart(now_s)
            return
        if self.vt is None:
            return
        if now_s >= self._next_maintenance_s - 1e-9:
            self._send(pad([Function.WORKING_SET_MAINTENANCE, 0, self.vt_version]))
            while self._next_maintenance_s <= now_s + 1e-9:
                self._next_maintenance_s += MAINTENANCE_PERIOD_S
        if self.state.startswith("wait ") and self.state != "wait status" and \
                now_s - self._state_s >= RESPONSE_TIMEOUT_S:
            self._restart(now_s)
            return
        if self.state in ("uploading", "end of pool") and self._idle():
            if self._to_send:
                self._send(self._to_send.popleft())
            elif self.state == "uploading":
                self.state = "end of pool"
            else:
                self._send(pad([Function.END_OF_OBJECT_POOL]))
                self._set("wait end of pool", now_s)
        if self.state == "connected" and self._commands and self._commands[0].sent_s is None:
            self._commands[0].sent_s = now_s
            self._send(self._commands[0].data)

    # -- internals -------------------------------------------------------------------------------

    def _idle(self) -> bool:
        if self.transport_idle is not None:
            return self.transport_idle()
        network = getattr(self.port, "network", None)
        transport = getattr(network, "transport", None)
        return not transport.busy() if transport is not None else True

    def _send(self, data: bytes) -> None:
        assert self.vt is not None
        self.port.send(ECU_TO_VT_PGN, data, self.vt, PRIORITY)

    def _set(self, state: str, now_s: float) -> None:
        self.state = state
        self._state_s = now_s

    def _restart(self, now_s: float) -> None:
        self.vt = None
        self.vt_status_s = None
        self._next_maintenance_s = math.inf
        self._to_send.clear()
        for c in self._commands:
            c.sent_s = None
        self.connected_s = None
        self._set("wait status", now_s)

    def _connected(self, now_s: float) -> None:
        self._set("connected", now_s)
        self.connected_s = now_s
        if self.on_connected is not None:
            self.on_connected(now_s)

    def _on_vt(self, msg: Received) -> None:
        d = msg.data
        if not d or len(d) < _NEEDED.get(d[0], 1):
            return      # a VT message too short for its function: not an answer (as the C build)
        t = msg.time_s
        function = d[0]
        if function == Function.VT_STATUS:
            if self.vt is None and self.state == "wait status" and self.refusal is None:
                self.vt = msg.source
                self._send_global_master()
                self._send(pad([Function.WORKING_SET_MAINTENANCE, 1, self.vt_version]))
                self._next_maintenance_s = t + MAINTENANCE_PERIOD_S
                size = sum(len(x) for x in self.transfers)
                self._send(pad(bytes([Function.GET_MEMORY, 0xFF]) + u32(size)))
                self._set("wait memory", t)
            if msg.source == self.vt:
                self.vt_status_s = t
                self.vt_data_mask = get16(d, 2)
            return
        if msg.source != self.vt or msg.destination != self.port.address:
            return
        self.responses.append((t, bytes(d)))
        state = self.state
        if function == Function.GET_MEMORY and state == "wait memory":
            if d[2] != 0:
                self.refusal = Refusal(d[2], 0xFFFF, 0xFFFF, 0, "not enough memory")
                self._set("refused", t)
                return
            self._send(pad([Function.GET_NUMBER_OF_SOFT_KEYS]))
            self._set("wait soft keys", t)
        elif function == Function.GET_NUMBER_OF_SOFT_KEYS and state == "wait soft keys":
            self._send(pad([Function.GET_TEXT_FONT_DATA]))
            self._set("wait fonts", t)
        elif function == Function.GET_TEXT_FONT_DATA and state == "wait fonts":
            self._send(pad([Function.GET_HARDWARE]))
            self._set("wait hardware", t)
        elif function == Function.GET_HARDWARE and state == "wait hardware":
            if self.version_label is not None:
                self._send(pad([Function.GET_VERSIONS]))
                self._set("wait versions", t)
            else:
                self._upload(t)
        elif function == Function.GET_VERSIONS_RESPONSE and state == "wait versions":
            labels = [bytes(d[2 + 7 * i:9 + 7 * i]) for i in range(d[1])]
            if self.version_label in labels:
                self._send(bytes([Function.LOAD_VERSION]) + (self.version_label or b""))
                self._set("wait load", t)
            else:
                self._upload(t)
        elif function == Function.LOAD_VERSION and state == "wait load":
            if d[5] == 0:
                self.loaded = True
                self._connected(t)
            else:
                self._upload(t)
        elif function == Function.END_OF_OBJECT_POOL and state == "wait end of pool":
            if d[1] != 0:
                self.refusal = Refusal(d[1], get16(d, 2), get16(d, 4), d[6],
                                       "end of object pool refused")
                self._set("refused", t)
            elif self.version_label is not None:
                self._send(bytes([Function.STORE_VERSION]) + self.version_label)
                self._set("wait store", t)
            else:
                self._connected(t)
        elif function == Function.STORE_VERSION and state == "wait store":
            self._connected(t)
        elif function in (Function.SOFT_KEY_ACTIVATION, Function.BUTTON_ACTIVATION):
            event = KeyEvent(t, get16(d, 2), get16(d, 4), d[6], KeyActivation(d[1] & 0x03),
                             function == Function.BUTTON_ACTIVATION)
            self.keys.append(event)
            self._send(pad(d[:7]))             # the activation response echoes it
            if self.on_key is not None:
                self.on_key(event)
        elif function == Function.VT_CHANGE_NUMERIC_VALUE:
            oid, value = get16(d, 1), get32(d, 4)
            self.numbers.append((t, oid, value))
            self._send(bytes([function]) + u16(oid) + b"\xff" + u32(value))
            if self.on_number is not None:
                self.on_number(oid, value, t)
        elif function == Function.VT_CHANGE_STRING_VALUE:
            oid, n = get16(d, 1), d[3]
            text = bytes(d[4:4 + n]).decode("latin-1")
            self.strings.append((t, oid, text))
            self._send(pad(bytes([function]) + u16(oid)))
            if self.on_string is not None:
                self.on_string(oid, text, t)
        elif self._commands and self._commands[0].sent_s is not None and \
                function == self._commands[0].data[0]:
            self._commands.popleft()

    def _send_global_master(self) -> None:
        self.port.send(WORKING_SET_MASTER_PGN, pad([1]), GLOBAL_ADDRESS, 6)

    def _upload(self, t: float) -> None:
        self._to_send = deque(bytes([Function.OBJECT_POOL_TRANSFER]) + bytes(x)
                              for x in self.transfers)
        self._set("uploading", t)
