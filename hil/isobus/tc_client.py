"""A Task Controller client (ISO 11783-10, version 4): the implement's side of process data.

:class:`TaskControllerClient` runs on an :class:`~hil.isobus.port.IsobusPort` like the rig's
own applications: no thread, no clock; the network calls :meth:`TaskControllerClient.tick` with
the run time (:meth:`TaskControllerClient.next_due` says when). What it does, in the order of
the standard's connection procedure:

1. waits for a TC status message (process data command 0xE) and binds to that TC;
2. sends the working-set master message (PGN 0xFE0D, one member) and starts its client task
   message (command 0xF) every 2 s, echoing the TC's "task totals active" bit;
3. asks for the TC's version and answers the TC's version request with its own;
4. asks for the language command (PGN 0xFE0F) and goes on after 2 s if none comes;
5. asks for the structure label and the localization label of the pool the TC holds for it:
   if both are its pool's, it activates without a transfer; otherwise it asks to transfer
   (request object pool transfer with the size), sends the pool (TP or ETP by the port), and
   activates;
6. connected: answers request value, applies value and set value commands through
   ``on_setpoint`` (process data acknowledge with the standard's error bits when it cannot),
   and sends the values the TC's measurement commands ask for (time interval, distance
   interval, change threshold, minimum and maximum within threshold).

It reconnects from step 1 when the TC status stops for 6 s (the TC is lost; ``on_connection``
is told, so the implement falls back to what its DDOP and the standard say), and from step 2
when the TC answers its process data with a negative acknowledgement (PGN 0xE800: the TC no
longer knows it, a restart shorter than 6 s). A refused pool (object pool activate response
with error bits, "not enough memory", a transfer error) ends the attempt: the client keeps the
error codes in :attr:`TaskControllerClient.refusal`, goes quiet and does not try again until
:meth:`TaskControllerClient.retry`; a timeout waiting for an answer starts over from step 1.

Where it differs from AgIsoStack++'s client (``isobus_task_controller_client.cpp`` at
509a920c), which is one peer, not the standard:

- The working-set master message is sent once per connection and on request (PGN 0xEA00): its
  transmission rate in ISO 11783-7 is "as required". The 1 s working set maintenance message is
  the virtual terminal's (ISO 11783-6), not the TC's; the TC keeps a client alive by its client
  task message every 2 s. AgIsoStack++ also sends it once.
- AgIsoStack++ waits a fixed 6 s after start-up before looking for a TC status; here
  ``startup_delay_s`` (0 by default) does that when a run wants it.
- On a structure label that is not its pool's, AgIsoStack++ deletes the stored pool first;
  here the new pool (with its own structure label) is transferred without the delete: a TC
  may keep several pools per client, told apart by their labels.
- Minimum and maximum *within* threshold (commands 6 and 7) send the value when it enters the
  window the thresholds set (above the minimum, below the maximum, both when both are set), and
  again each time it re-enters; AgIsoStack++ sends when the value goes above the maximum or
  below the minimum, the window's outside.
- A TC restart shorter than the 6 s status timeout is noticed from the TC's negative
  acknowledgement, global or addressed (J1939-21 sends it to the global address with the
  acknowledged address in byte 5); AgIsoStack++ hears only addressed ones.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum

from hil.errors import FrameError
from hil.isobus import process_data as pd
from hil.isobus.ddi import REQUEST_DEFAULT_PROCESS_DATA
from hil.isobus.ddop import (
    ActivationError,
    DdopError,
    ElementType,
    ObjectPool,
    PoolError,
    ProcessData,
    ProcessDataProperty,
    TriggerMethod,
)
from hil.isobus.port import GLOBAL_ADDRESS, IsobusPort, Received
from hil.isobus.process_data import AckError, Command, ElementCommand

__all__ = [
    "CLIENT_TASK_PERIOD_S",
    "LANGUAGE_COMMAND_PGN",
    "ClientEvent",
    "ClientState",
    "Refusal",
    "TaskControllerClient",
]

ACKNOWLEDGEMENT_PGN = 0xE800
REQUEST_PGN = 0xEA00
LANGUAGE_COMMAND_PGN = 0xFE0F

CLIENT_TASK_PERIOD_S = 2.0
"""The client task message period (ISO 11783-10)."""
TC_STATUS_TIMEOUT_S = 6.0
"""A TC whose status message stops this long is lost (ISO 11783-10)."""
RESPONSE_TIMEOUT_S = 2.0
"""How long the client waits for an answer during the connection before starting over."""
TRANSFER_TIMEOUT_S = 10.0
"""How long it waits for the object pool transfer response: the transfer itself goes by TP or
ETP, whose own timeouts (up to 1.25 s per step, ISO 11783-3) come first; 10 s leaves room for a
pool of some kilobytes on a busy bus."""
LANGUAGE_TIMEOUT_S = 2.0
"""How long it waits for the language command before going on without it."""
TRIGGER_POLL_S = 0.01
"""How often change, threshold and distance triggers read their values (100 Hz)."""

PRIORITY_DEFAULT = 5
PRIORITY_TRANSFER = 7


class ClientState(Enum):
    """Where the client is in the connection procedure."""

    STARTING = "starting"
    WAIT_STATUS = "waiting for TC status"
    WAIT_VERSION = "waiting for the TC's version"
    WAIT_LANGUAGE = "waiting for the language command"
    WAIT_STRUCTURE_LABEL = "waiting for the structure label"
    WAIT_LOCALIZATION_LABEL = "waiting for the localization label"
    WAIT_TRANSFER_PERMISSION = "waiting for the request object pool transfer response"
    WAIT_TRANSFER_RESPONSE = "waiting for the object pool transfer response"
    WAIT_ACTIVATION = "waiting for the object pool activate response"
    CONNECTED = "connected"
    REFUSED = "refused"


@dataclass(frozen=True)
class ClientEvent:
    """Something the client went through: a state change, a loss, a refusal, a NACK."""

    time_s: float
    kind: str
    detail: str = ""


@dataclass(frozen=True)
class Refusal:
    """Why the TC did not take the pool: the object pool activate response's codes, or the
    memory/transfer answer that stopped the client before activation.

    Attributes
    ----------
    time_s : float
    reason : str
        In words, with the codes named.
    activation_errors : int
        :class:`~hil.isobus.ddop.ActivationError` bits (0 when refused before activation).
    parent_id, object_id : int
        The faulty object and its parent (0xFFFF: none named).
    pool_errors : int
        :class:`~hil.isobus.ddop.PoolError` bits.
    """

    time_s: float
    reason: str
    activation_errors: int = 0
    parent_id: int = 0xFFFF
    object_id: int = 0xFFFF
    pool_errors: int = 0


SetpointHandler = Callable[[int, int, int, float], AckError | None]
"""``on_setpoint(element, ddi, value, time_s)``: apply a value command; return the error bits
(or ``None`` / ``AckError.NONE``) for the process data acknowledge."""
ValueReader = Callable[[int, int, float], int | None]
"""``read_value(element, ddi, time_s)``: the current raw value of a process data entity, or
``None`` when the implement has none to give."""


@dataclass
class _Trigger:
    """The measurement commands the TC set on one (element, DDI)."""

    time_ms: int | None = None
    next_time_s: float = math.inf
    distance_mm: int | None = None
    distance_from_mm: float | None = None
    change: int | None = None
    last_sent: int | None = None
    minimum: int | None = None
    maximum: int | None = None
    inside: bool = False

    @property
    def polled(self) -> bool:
        return (self.distance_mm is not None or self.change is not None
                or self.minimum is not None or self.maximum is not None)


@dataclass
class _Connection:
    """What a connection attempt knows; dropped when the client starts over."""

    tc_address: int
    started_s: float
    tc_version: pd.Version | None = None
    triggers: dict[tuple[int, int], _Trigger] = field(default_factory=dict)


class TaskControllerClient:
    """An implement's Task Controller client (see the module docstring).

    Parameters
    ----------
    port : IsobusPort
        The client's control function (the working-set master).
    pool : ObjectPool
        Its device descriptor object pool; the device object's NAME should be the port's.
    on_setpoint : callable
        ``(element, ddi, value, time_s) -> AckError | None``: a value command from the TC.
    read_value : callable
        ``(element, ddi, time_s) -> int | None``: the implement's current value, for request
        value and the measurement triggers.
    distance_mm : callable, optional
        ``(time_s) -> float``: distance travelled (e.g. the TECU's ground-based distance), for
        distance interval triggers; without it such triggers are acknowledged as not supported.
    on_connection : callable, optional
        ``(connected, time_s)``: called when the pool becomes active and when the connection is
        lost (TC status timeout, TC restart, refusal).
    version : Version, optional
        The client's version message; by default version 4 with the pool's section count.
    tc_address : int, optional
        Talk only to the TC at this address; by default the first TC whose status it hears.
    startup_delay_s : float
        Time after start before it looks for a TC status.
    members : int
        Working-set members in the working-set master message.
    """

    def __init__(self, port: IsobusPort, pool: ObjectPool, *, on_setpoint: SetpointHandler,
                 read_value: ValueReader,
                 distance_mm: Callable[[float], float] | None = None,
                 on_connection: Callable[[bool, float], None] | None = None,
                 version: pd.Version | None = None, tc_address: int | None = None,
                 startup_delay_s: float = 0.0, members: int = 1) -> None:
        if not 1 <= members <= 255:
            raise ValueError(f"working-set members must be 1 .. 255, got {members}")
        self.port = port
        self.pool = pool
        self.on_setpoint = on_setpoint
        self.read_value = read_value
        self.distance_mm = distance_mm
        self.on_connection = on_connection
        sections = sum(1 for e in pool.elements if e.element_type == ElementType.SECTION)
        self.version = version or pd.Version(
            4, int(pd.VersionOption.DOCUMENTATION
                   | (pd.VersionOption.IMPLEMENT_SECTION_CONTROL if sections else 0)),
            booms=1 if sections else 0, sections=min(sections, 255), channels=0)
        self.tc_address_wanted = tc_address
        self.startup_delay_s = startup_delay_s
        self.members = members
        self.state = ClientState.STARTING
        self.events: list[ClientEvent] = []
        self.refusal: Refusal | None = None
        self.language: bytes | None = None
        self.connections = 0
        """How many times the pool became active."""
        self.transfers = 0
        """How many times the pool was transferred."""
        self.task_active = False
        self._conn: _Connection | None = None
        self._started_s: float | None = None
        self._state_s = 0.0
        self._last_status_s = -math.inf
        self._last_status_from: int | None = None
        self._next_task_s = math.inf
        self._now_s = 0.0
        self._next_poll_s = 0.0
        self._pool_bytes: bytes | None = None
        port.subscribe(pd.PROCESS_DATA_PGN, self._on_process_data)
        port.subscribe(ACKNOWLEDGEMENT_PGN, self._on_acknowledgement)
        port.subscribe(REQUEST_PGN, self._on_request)
        port.subscribe(LANGUAGE_COMMAND_PGN, self._on_language)

    # --- what the application sees ----------------------------------------------------------

    @property
    def connected(self) -> bool:
        """Whether the pool is active on the TC (process data flows)."""
        return self.state is ClientState.CONNECTED

    @property
    def tc_address(self) -> int | None:
        """The TC the client talks to, ``None`` before it has heard one."""
        return self._conn.tc_address if self._conn is not None else None

    def triggers(self) -> dict[tuple[int, int], dict[str, int]]:
        """The measurement commands in force: ``(element, DDI) -> {kind: value}``."""
        if self._conn is None:
            return {}
        out: dict[tuple[int, int], dict[str, int]] = {}
        for key, trig in self._conn.triggers.items():
            kinds = {"time_ms": trig.time_ms, "distance_mm": trig.distance_mm,
                     "change": trig.change, "minimum": trig.minimum, "maximum": trig.maximum}
            out[key] = {k: v for k, v in kinds.items() if v is not None}
        return out

    def retry(self, pool: ObjectPool | None = None) -> None:
        """Try again after a refusal, with a corrected ``pool`` if given."""
        if pool is not None:
            self.pool = pool
            self._pool_bytes = None
        self.refusal = None
        self._restart(self._now_s, "retry")

    # --- timers -------------------------------------------------------------------------------

    def next_due(self, now_s: float) -> float:
        """The next run time at which :meth:`tick` has something to do."""
        if self._started_s is None:
            return now_s
        if self.port.address is None:
            return now_s + TRIGGER_POLL_S    # the claim has not settled: look again soon
        if self.state is ClientState.REFUSED:
            return math.inf
        if self.state is ClientState.STARTING:
            return self._started_s + self.startup_delay_s
        due = self._next_task_s
        if self.state is not ClientState.WAIT_STATUS or self._conn is not None:
            due = min(due, self._last_status_s + TC_STATUS_TIMEOUT_S)
        timeout = self._timeout()
        if timeout is not None:
            due = min(due, self._state_s + timeout)
        if self.state is ClientState.CONNECTED and self._conn is not None:
            for trig in self._conn.triggers.values():
                due = min(due, trig.next_time_s)
                if trig.polled:
                    due = min(due, self._next_poll_s)
        return due

    def tick(self, now_s: float) -> None:
        """Advance to ``now_s``: client task, timeouts, measurement triggers."""
        self._now_s = now_s
        if self._started_s is None:
            self._started_s = now_s
        if self.port.address is None or self.state is ClientState.REFUSED:
            return
        if self.state is ClientState.STARTING:
            if now_s >= self._started_s + self.startup_delay_s:
                self._set_state(ClientState.WAIT_STATUS, now_s)
                heard = self._last_status_from
                if heard is not None and now_s - self._last_status_s < CLIENT_TASK_PERIOD_S:
                    self._begin(heard, now_s)    # a status heard while starting: the TC is up
            return
        if self._conn is not None and now_s - self._last_status_s >= TC_STATUS_TIMEOUT_S:
            self._lose(now_s, f"no TC status for {now_s - self._last_status_s:.1f} s")
            return
        timeout = self._timeout()
        if timeout is not None and now_s - self._state_s >= timeout:
            if self.state is ClientState.WAIT_LANGUAGE:
                self._event(now_s, "language", "no language command: going on without it")
                self._request_structure_label(now_s)
            else:
                self._lose(now_s, f"timeout {self.state.value}")
                return
        if self._conn is not None and now_s >= self._next_task_s:
            self._send(pd.ClientTask(self.task_active))
            while self._next_task_s <= now_s:
                self._next_task_s += CLIENT_TASK_PERIOD_S
        if self.state is ClientState.CONNECTED:
            self._run_triggers(now_s)
            self._next_poll_s = now_s + TRIGGER_POLL_S

    def _timeout(self) -> float | None:
        return {ClientState.WAIT_VERSION: RESPONSE_TIMEOUT_S,
                ClientState.WAIT_LANGUAGE: LANGUAGE_TIMEOUT_S,
                ClientState.WAIT_STRUCTURE_LABEL: RESPONSE_TIMEOUT_S,
                ClientState.WAIT_LOCALIZATION_LABEL: RESPONSE_TIMEOUT_S,
                ClientState.WAIT_TRANSFER_PERMISSION: RESPONSE_TIMEOUT_S,
                ClientState.WAIT_TRANSFER_RESPONSE: TRANSFER_TIMEOUT_S,
                ClientState.WAIT_ACTIVATION: RESPONSE_TIMEOUT_S}.get(self.state)

    # --- state --------------------------------------------------------------------------------

    def _event(self, time_s: float, kind: str, detail: str = "") -> None:
        self.events.append(ClientEvent(time_s, kind, detail))

    def _set_state(self, state: ClientState, time_s: float) -> None:
        if state is not self.state:
            self._event(time_s, "state", state.value)
        self.state = state
        self._state_s = time_s

    def _lose(self, time_s: float, why: str) -> None:
        """Back to waiting for a TC status: the connection is gone."""
        was = self.state is ClientState.CONNECTED
        self._event(time_s, "lost", why)
        self._conn = None
        self._next_task_s = math.inf
        self.task_active = False
        self._set_state(ClientState.WAIT_STATUS, time_s)
        if was and self.on_connection is not None:
            self.on_connection(False, time_s)

    def _restart(self, time_s: float, why: str) -> None:
        """Start the procedure again with the same TC (it no longer knows the client)."""
        tc = self._conn.tc_address if self._conn is not None else None
        was = self.state is ClientState.CONNECTED
        self._event(time_s, "restart", why)
        self._conn = None
        self._next_task_s = math.inf
        self._set_state(ClientState.WAIT_STATUS, time_s)
        if was and self.on_connection is not None:
            self.on_connection(False, time_s)
        if tc is not None and time_s - self._last_status_s < TC_STATUS_TIMEOUT_S:
            self._begin(tc, time_s)

    def _refuse(self, refusal: Refusal) -> None:
        self.refusal = refusal
        was = self.state is ClientState.CONNECTED
        self._event(refusal.time_s, "refused", refusal.reason)
        self._conn = None
        self._next_task_s = math.inf
        self._set_state(ClientState.REFUSED, refusal.time_s)
        if was and self.on_connection is not None:
            self.on_connection(False, refusal.time_s)

    def _begin(self, tc: int, time_s: float) -> None:
        """Steps 2 and 3: working-set master, client task, version request."""
        self._conn = _Connection(tc, time_s)
        self.port.send(pd.WORKING_SET_MASTER_PGN,
                       pd.encode_working_set_master(pd.WorkingSetMaster(self.members)),
                       GLOBAL_ADDRESS, 7)
        self._send(pd.ClientTask(self.task_active))
        self._next_task_s = time_s + CLIENT_TASK_PERIOD_S
        self._send(pd.RequestVersion())
        self._set_state(ClientState.WAIT_VERSION, time_s)

    # --- sending ------------------------------------------------------------------------------

    def _send(self, message: pd.ProcessDataMessage, priority: int = PRIORITY_DEFAULT) -> None:
        if self._conn is None:
            return
        self.port.send(pd.PROCESS_DATA_PGN, pd.encode(message), self._conn.tc_address, priority)

    def _pool_for(self, tc_version: int) -> bytes:
        """The pool's bytes in the TC's version when the TC is older than the pool."""
        if self._pool_bytes is None:
            pool = self.pool
            if 0 < tc_version < pool.version:
                pool = ObjectPool(pool.objects, tc_version)
            self._pool_bytes = pool.to_bytes()
        return self._pool_bytes

    def _request_structure_label(self, time_s: float) -> None:
        self._send(pd.RequestStructureLabel())
        self._set_state(ClientState.WAIT_STRUCTURE_LABEL, time_s)

    def _request_transfer(self, time_s: float) -> None:
        assert self._conn is not None
        version = self._conn.tc_version.version if self._conn.tc_version else 4
        try:
            raw = self._pool_for(version)
        except (DdopError, FrameError, ValueError) as exc:
            self._refuse(Refusal(time_s, f"the pool cannot be written for the TC's version "
                                         f"{version}: {exc}"))
            return
        self._send(pd.RequestObjectPoolTransfer(len(raw)))
        self._set_state(ClientState.WAIT_TRANSFER_PERMISSION, time_s)

    def _activate(self, time_s: float) -> None:
        self._send(pd.ObjectPoolActivate(True))
        self._set_state(ClientState.WAIT_ACTIVATION, time_s)

    def _ack(self, element: int, ddi: int, errors: AckError, command: int) -> None:
        self._send(pd.ProcessDataAcknowledge(element, ddi, errors, command), 4)

    def _send_value(self, element: int, ddi: int, value: int) -> None:
        self._send(ElementCommand(Command.VALUE, element, ddi, value))

    # --- receiving ----------------------------------------------------------------------------

    def _from_tc(self, msg: Received) -> bool:
        return self._conn is not None and msg.source == self._conn.tc_address

    def _on_process_data(self, msg: Received) -> None:
        if self.state is ClientState.REFUSED:
            return
        try:
            message = pd.decode(msg.data)
        except FrameError as exc:
            self._event(msg.time_s, "bad frame", str(exc))
            return
        if isinstance(message, pd.TaskControllerStatus):
            self._on_status(message, msg)
            return
        if self.port.address is None or not self._from_tc(msg) \
                or msg.destination != self.port.address:
            return
        self._handle(message, msg.time_s)

    def _on_status(self, status: pd.TaskControllerStatus, msg: Received) -> None:
        if self._conn is not None and msg.source != self._conn.tc_address:
            return    # another TC: this client talks to one
        if self._conn is None and self.tc_address_wanted not in (None, msg.source):
            return
        self._last_status_s = msg.time_s
        self._last_status_from = msg.source
        self.task_active = bool(status.status & pd.ServerStatus.TASK_TOTALS_ACTIVE)
        if self._conn is None and self.state is ClientState.WAIT_STATUS \
                and self.port.address is not None:
            self._begin(msg.source, msg.time_s)

    def _handle(self, message: pd.ProcessDataMessage, t: float) -> None:
        conn = self._conn
        assert conn is not None
        match message:
            case pd.RequestVersion():
                self._send(self.version)
            case pd.Version():
                conn.tc_version = message
                if self.state is ClientState.WAIT_VERSION:
                    self._event(t, "tc version",
                                f"version {message.version}, options 0x{message.options:02X}, "
                                f"{message.booms} booms, {message.sections} sections")
                    self.port.send(REQUEST_PGN, LANGUAGE_COMMAND_PGN.to_bytes(3, "little"),
                                   GLOBAL_ADDRESS, 6)
                    self._set_state(ClientState.WAIT_LANGUAGE, t)
            case pd.StructureLabel() if self.state is ClientState.WAIT_STRUCTURE_LABEL:
                device = self.pool.device
                if message.label == device.structure_label and (
                        not message.extended
                        or message.extended == device.extended_structure_label):
                    self._send(pd.RequestLocalizationLabel())
                    self._set_state(ClientState.WAIT_LOCALIZATION_LABEL, t)
                else:
                    self._request_transfer(t)
            case pd.LocalizationLabel() if self.state is ClientState.WAIT_LOCALIZATION_LABEL:
                if message.label == self.pool.device.localization_label:
                    self._event(t, "pool known", "labels match: no transfer")
                    self._activate(t)
                else:
                    self._request_transfer(t)
            case pd.RequestObjectPoolTransferResponse() \
                    if self.state is ClientState.WAIT_TRANSFER_PERMISSION:
                if not message.enough_memory:
                    self._refuse(Refusal(t, "the TC has not enough memory for the pool "
                                            "(request object pool transfer response 1)"))
                    return
                assert self._pool_bytes is not None
                self.transfers += 1
                self._send(pd.ObjectPoolTransfer(self._pool_bytes), PRIORITY_TRANSFER)
                self._set_state(ClientState.WAIT_TRANSFER_RESPONSE, t)
            case pd.ObjectPoolTransferResponse() \
                    if self.state is ClientState.WAIT_TRANSFER_RESPONSE:
                if message.errors:
                    what = "out of memory" if message.errors & 0x01 else "other error"
                    self._refuse(Refusal(t, f"object pool transfer response error bits "
                                            f"0x{message.errors:02X} ({what}), "
                                            f"{message.size} bytes taken"))
                    return
                self._activate(t)
            case pd.ObjectPoolActivateResponse() if self.state is ClientState.WAIT_ACTIVATION:
                if message.activation_errors:
                    self._refuse(_refusal(t, message))
                    return
                self._set_state(ClientState.CONNECTED, t)
                self.connections += 1
                if self.on_connection is not None:
                    self.on_connection(True, t)
            case pd.DeleteObjectPoolResponse() | pd.ObjectPoolActivateResponse() \
                    | pd.StructureLabel() | pd.LocalizationLabel():
                self._event(t, "ignored", f"{type(message).__name__} while "
                                          f"{self.state.value}")
            case ElementCommand():
                self._on_element_command(message, t)
            case pd.ProcessDataAcknowledge():
                self._event(t, "tc acknowledge",
                            f"element {message.element} DDI {message.ddi} errors "
                            f"0x{int(message.errors):02X} to command {message.command}")
            case _:
                self._event(t, "ignored", f"{type(message).__name__} from the TC")

    def _on_element_command(self, message: ElementCommand, t: float) -> None:
        if self.state is not ClientState.CONNECTED:
            # process data before activation: the pool is not active, nothing to answer with
            self._ack(message.element, message.ddi, AckError.COMMAND_NOT_SUPPORTED,
                      message.command)
            return
        element, ddi = message.element, message.ddi
        if message.command == Command.REQUEST_VALUE and ddi == REQUEST_DEFAULT_PROCESS_DATA:
            self._send_default_set(element, t)
            return
        dpd, errors = self._entity(element, ddi)
        if dpd is None:
            self._ack(element, ddi, errors, message.command)
            return
        match message.command:
            case Command.REQUEST_VALUE:
                value = self.read_value(element, ddi, t)
                if value is None:
                    self._ack(element, ddi, AckError.DDI_NOT_SUPPORTED_BY_ELEMENT,
                              message.command)
                else:
                    self._send_value(element, ddi, value)
            case Command.VALUE | Command.SET_VALUE_AND_ACKNOWLEDGE:
                if not dpd.properties & ProcessDataProperty.SETTABLE:
                    result: AckError | None = AckError.NOT_SETTABLE
                else:
                    result = self.on_setpoint(element, ddi, message.value, t)
                errors = AckError(result or 0)
                if errors or message.command == Command.SET_VALUE_AND_ACKNOWLEDGE:
                    self._ack(element, ddi, errors, message.command)
            case _:
                self._set_trigger(dpd, message, t)

    def _entity(self, element: int, ddi: int) -> tuple[ProcessData | None, AckError]:
        if self.pool.element(element) is None:
            return None, AckError.INVALID_ELEMENT_NUMBER
        dpd = self.pool.process_data(element, ddi)
        if dpd is None:
            return None, AckError.DDI_NOT_SUPPORTED_BY_ELEMENT
        return dpd, AckError.NONE

    def _send_default_set(self, element: int, t: float) -> None:
        """Request value of DDI 0xDFFF: the current value of every default set DPD."""
        for det in self.pool.elements:
            for child in self.pool.children(det):
                if isinstance(child, ProcessData) and child.ddi != REQUEST_DEFAULT_PROCESS_DATA \
                        and child.properties & ProcessDataProperty.MEMBER_OF_DEFAULT_SET:
                    value = self.read_value(det.element_number, child.ddi, t)
                    if value is not None:
                        self._send_value(det.element_number, child.ddi, value)

    def _set_trigger(self, dpd: ProcessData, message: ElementCommand, t: float) -> None:
        conn = self._conn
        assert conn is not None
        methods = {Command.MEASUREMENT_TIME_INTERVAL: TriggerMethod.TIME_INTERVAL,
                   Command.MEASUREMENT_DISTANCE_INTERVAL: TriggerMethod.DISTANCE_INTERVAL,
                   Command.MEASUREMENT_MINIMUM_THRESHOLD: TriggerMethod.THRESHOLD_LIMITS,
                   Command.MEASUREMENT_MAXIMUM_THRESHOLD: TriggerMethod.THRESHOLD_LIMITS,
                   Command.MEASUREMENT_CHANGE_THRESHOLD: TriggerMethod.ON_CHANGE}
        command = Command(message.command)
        method = methods.get(command)
        if method is None or not dpd.trigger_methods & method or (
                command == Command.MEASUREMENT_DISTANCE_INTERVAL and self.distance_mm is None):
            self._ack(message.element, message.ddi, AckError.TRIGGER_METHOD_NOT_SUPPORTED,
                      message.command)
            return
        value = message.value
        if command in (Command.MEASUREMENT_TIME_INTERVAL, Command.MEASUREMENT_DISTANCE_INTERVAL,
                       Command.MEASUREMENT_CHANGE_THRESHOLD) and value <= 0:
            # the standard gives no meaning to a zero or negative interval; refuse it rather
            # than send on every poll
            self._ack(message.element, message.ddi, AckError.INVALID_INTERVAL_OR_THRESHOLD,
                      message.command)
            return
        trig = conn.triggers.setdefault((message.element, message.ddi), _Trigger())
        match command:
            case Command.MEASUREMENT_TIME_INTERVAL:
                trig.time_ms = value
                trig.next_time_s = t + value / 1000.0
            case Command.MEASUREMENT_DISTANCE_INTERVAL:
                assert self.distance_mm is not None
                trig.distance_mm = value
                trig.distance_from_mm = self.distance_mm(t)
            case Command.MEASUREMENT_CHANGE_THRESHOLD:
                trig.change = value
            case Command.MEASUREMENT_MINIMUM_THRESHOLD:
                trig.minimum = value
                trig.inside = False
            case Command.MEASUREMENT_MAXIMUM_THRESHOLD:
                trig.maximum = value
                trig.inside = False
        self._event(t, "trigger", f"element {message.element} DDI {message.ddi}: "
                                  f"{command.name.lower()} {value}")

    def _run_triggers(self, now_s: float) -> None:
        conn = self._conn
        assert conn is not None
        distance = self.distance_mm(now_s) if self.distance_mm is not None else None
        for (element, ddi), trig in conn.triggers.items():
            send = False
            if trig.time_ms is not None and now_s >= trig.next_time_s:
                send = True
                step = trig.time_ms / 1000.0
                while trig.next_time_s <= now_s:
                    trig.next_time_s += step
            if trig.distance_mm is not None and distance is not None \
                    and trig.distance_from_mm is not None \
                    and abs(distance - trig.distance_from_mm) >= trig.distance_mm:
                send = True
                trig.distance_from_mm = distance
            value: int | None = None
            if trig.change is not None or trig.minimum is not None or trig.maximum is not None:
                value = self.read_value(element, ddi, now_s)
            if value is not None:
                if trig.change is not None and (
                        trig.last_sent is None or abs(value - trig.last_sent) >= trig.change):
                    send = True
                if trig.minimum is not None or trig.maximum is not None:
                    inside = ((trig.minimum is None or value > trig.minimum)
                              and (trig.maximum is None or value < trig.maximum))
                    if inside and not trig.inside:
                        send = True
                    trig.inside = inside
            if not send:
                continue
            if value is None:
                value = self.read_value(element, ddi, now_s)
            if value is not None:
                self._send_value(element, ddi, value)
                trig.last_sent = value

    def _on_acknowledgement(self, msg: Received) -> None:
        """A NACK of process data from the TC: it does not know this client (it restarted)."""
        if not self._from_tc(msg) or len(msg.data) < 8 or msg.data[0] != 0x01:
            return
        if int.from_bytes(msg.data[5:8], "little") != pd.PROCESS_DATA_PGN:
            return
        if msg.destination == GLOBAL_ADDRESS and msg.data[4] != self.port.address:
            return
        self._restart(msg.time_s, "the TC answered process data with a NACK")

    def _on_request(self, msg: Received) -> None:
        if len(msg.data) >= 3 and self._conn is not None and \
                int.from_bytes(msg.data[:3], "little") == pd.WORKING_SET_MASTER_PGN:
            self.port.send(pd.WORKING_SET_MASTER_PGN,
                           pd.encode_working_set_master(pd.WorkingSetMaster(self.members)),
                           GLOBAL_ADDRESS, 7)

    def _on_language(self, msg: Received) -> None:
        if len(msg.data) < 8:
            return
        self.language = bytes(msg.data[:8])
        if self.state is ClientState.WAIT_LANGUAGE:
            self._event(msg.time_s, "language", self.language[:2].decode("ascii", "replace"))
            self._request_structure_label(msg.time_s)


def _refusal(time_s: float, response: pd.ObjectPoolActivateResponse) -> Refusal:
    activation = ActivationError(response.activation_errors & 0x0F)
    pool_errors = PoolError(response.pool_errors & 0x0F)
    names = [e.name.lower() for e in ActivationError if e and e in activation]
    pool_names = [e.name.lower() for e in PoolError if e and e in pool_errors]
    reason = (f"object pool activate response: activation errors "
              f"0x{response.activation_errors:02X} ({', '.join(names) or 'unnamed'}), "
              f"object {response.object_id} (parent {response.parent_id}), pool errors "
              f"0x{response.pool_errors:02X} ({', '.join(pool_names) or 'none'})")
    return Refusal(time_s, reason, response.activation_errors, response.parent_id,
                   response.object_id, response.pool_errors)
