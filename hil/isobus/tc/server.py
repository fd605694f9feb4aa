"""The Task Controller server (ISO 11783-10, version 4): TC-BAS process data with set-points.

The server runs on an :class:`~hil.isobus.port.IsobusPort` and keeps its own timers through
:meth:`TaskControllerServer.tick`. What a client sees:

- the TC status (process data command 0xE) every 2 s, broadcast;
- on its working-set master message, a new session, for the NAME that claimed the client's
  address (no claim, no session; never for 0xFE or 0xFF);
- the version message (v4 and the options, booms, sections and channels the TC supports) when
  the client asks, and then, once, the TC's request for the client's version: in the order of
  ISO 11783-10's connection procedure (the client asks first, after the TC status), which
  AgIsoStack++'s client checks ("Server requested version information at a strange time" when
  the TC asks before it has answered);
- the language command (PGN 0xFE0F) when it requests it;
- structure and localization labels answered from a :class:`~hil.isobus.tc.store.PoolStore`,
  so a client whose pool is known skips the transfer;
- the object pool transfer (received whole through the port), parsed with the client's version,
  validated with every rule of :mod:`hil.isobus.ddop.validate`, and activated or refused with the
  error codes and the faulty object's id;
- after activation: the measurement triggers of a :class:`~hil.isobus.tc.triggers.TriggerPlan`,
  then set-points from a :data:`~hil.isobus.tc.setpoints.SetpointSource`;
- every value it sends logged (:attr:`TaskControllerServer.values`), its process data
  acknowledgements answered or recorded;
- its session dropped after 6 s without its client task message or working-set master, and
  ended at once when another NAME claims its address or its NAME moves (the session belongs to
  the NAME: the newcomer's values are not the implement's, and it gets no set-points);
- a negative acknowledgement (PGN 0xE800) for process data before its working-set master, at
  most one per address and second (the rest counted, :mod:`hil.isobus.tc.limiter`).

A pool the TC cannot use though it follows the standard's rules (the rig's tractor needs a
working width on every section) is refused at activation by the ``usable`` check with the
standard's error codes, like any other. With ``isolate_errors`` an exception while handling a
client's message or computing its set-points ends that client's session (event
``client error``), not the TC. With a ``checker`` (an executor) the pool is parsed and checked
off the network's thread, so the tractor ECU's messages stay on time while a large pool is
checked; the activate response goes out when the check is done.

When the TC loses its own address to a lower NAME (ISO 11783-5) every session ends and the
event ``address lost`` says so; the network re-claims another address for a self-configurable
TC NAME (``address claimed`` when it holds one), and clients find the TC again by its status.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from concurrent.futures import Executor, Future
from dataclasses import dataclass, field

from hil.errors import FrameError
from hil.isobus import process_data as pd
from hil.isobus.ddi import DDI_TABLE, INT32_MIN, UINT32_MAX
from hil.isobus.ddop import (
    ActivationError,
    DdopError,
    ObjectPool,
    PoolError,
)
from hil.isobus.port import GLOBAL_ADDRESS, NULL_ADDRESS, IsobusPort, Received
from hil.isobus.process_data import AckError, Command, ElementCommand
from hil.isobus.tc.limiter import RateLimiter
from hil.isobus.tc.records import Event, EventKind, LoggedValue, ReceivedAcknowledge, Record
from hil.isobus.tc.setpoints import SetpointRequest, SetpointSource, no_setpoints
from hil.isobus.tc.store import ClientKey, PoolStore
from hil.isobus.tc.triggers import TriggerPlan

ACKNOWLEDGEMENT_PGN = 0xE800
REQUEST_PGN = 0xEA00
LANGUAGE_COMMAND_PGN = 0xFE0F
ADDRESS_CLAIMED_PGN = 0xEE00

UNSOLICITED_PERIOD_S = 1.0
"""Per address, at most one rejected message is logged (and one NACK sent) per this period;
the rest are counted and the count logged when the period ends."""
CHECK_POLL_S = 0.005
"""How often the TC looks whether a pool checked off its thread is done."""

STATUS_PERIOD_S = 2.0
"""The TC status period (ISO 11783-10)."""
CLIENT_TIMEOUT_S = 6.0
"""A client silent this long (no client task, no working-set master) is dropped."""
MIN_STATUS_INTERVAL_S = 0.2
"""A changed status goes out at once, but never sooner than this after the last one."""
SETPOINT_PERIOD_S = 0.1
"""How often the TC asks its set-point source (the map, coverage) and sends what changed:
10 Hz, the rate at which a TC's section control and map look-up run (one control step of a
100 ms implement)."""

PRIORITY_STATUS = 3
PRIORITY_ACK = 4
PRIORITY_DEFAULT = 5

DEFAULT_LANGUAGE_COMMAND = b"en" + bytes([0x40, 0x00, 0x00, 0x00, 0xFF, 0xFF])
"""English, decimal point, 24 h, metric units."""


def _check_setpoint(element: int, ddi: int, value: int) -> None:
    """A set-point source's answer must fit 32 bits and the DDI's range: a value outside is the
    rig's mistake, and sending it would test the implement on something no TC sends."""
    if not INT32_MIN <= value <= UINT32_MAX:
        raise ValueError(f"set-point source: {value} for DDI {ddi} on element {element} does "
                         f"not fit 32 bits")
    entry = DDI_TABLE.get(ddi)
    if entry is None:
        return
    raw = value & UINT32_MAX if entry.unsigned else (
        value - (1 << 32) if value > 2**31 - 1 else value)
    if not entry.in_range(raw):
        raise ValueError(f"set-point source: {value} for DDI {ddi} ({entry.name}) on element "
                         f"{element} is outside {entry.raw_min} .. {entry.raw_max}")


@dataclass
class ClientSession:
    """The TC's state of one connected client (volatile: lost on a restart)."""

    address: int
    key: ClientKey
    name: int | None
    connected_s: float
    last_seen_s: float
    version: int | None = None
    #: whether the TC asked for the client's version (once, after answering the client's)
    version_asked: bool = False
    #: a pool being checked off the network's thread: (future of the pool, its bytes)
    checking: tuple[Future[ObjectPool], bytes] | None = None
    transfer: bytearray = field(default_factory=bytearray)
    announced_size: int | None = None
    pool: ObjectPool | None = None
    pool_raw: bytes = b""
    triggers_due: bool = False
    task_active: bool = False
    sent_setpoints: dict[tuple[int, int], tuple[int, float]] = field(default_factory=dict)
    settable: tuple[tuple[int, int], ...] = ()

    @property
    def active(self) -> bool:
        """Whether the client's pool is active (process data flows)."""
        return self.pool is not None


@dataclass(frozen=True)
class ServerOptions:
    """What the TC reports in its version message.

    Attributes
    ----------
    version : int
        ISO 11783-10 version: 4 (second edition).
    options : int
        :class:`~hil.isobus.process_data.VersionOption` bits; TC-BAS documentation by default.
    booms, sections, channels : int
        Most booms, sections and position-based control channels the TC supports.
    memory_bytes : int
        The largest pool the TC accepts (request object pool transfer answers "not enough
        memory" beyond it).
    """

    version: int = 4
    options: int = int(pd.VersionOption.DOCUMENTATION)
    booms: int = 1
    sections: int = 16
    channels: int = 1
    memory_bytes: int = 1 << 20


class TaskControllerServer:
    """A Task Controller on an ISOBUS port.

    Parameters
    ----------
    port : IsobusPort
        The network seam: the TC's claimed address, send, subscribe, NAME look-up.
    options : ServerOptions
        Version, capabilities, memory.
    store : PoolStore, optional
        Stored pools; pass the same store to a restarted server (its non-volatile memory).
    setpoints : SetpointSource
        Set-point values per element and DDI.
    triggers : TriggerPlan
        The measurement commands sent after activation.
    setpoint_refresh_s : float or None
        Re-send an unchanged set-point this often (``None``: only on change).
    on_value : callable, optional
        Called with every :class:`~hil.isobus.tc.records.LoggedValue` as it is logged (the
        as-applied recorder's hook).
    language_command : bytes or None
        The 8-byte language command payload sent on request; ``None`` when another of the rig's
        control functions (the tractor ECU, a terminal) answers language requests.
    nack_to_client : bool
        Address the negative acknowledgement to the client instead of to everyone. J1939-21
        (which ISO 11783-3 follows) sends the acknowledgement PGN to the global address, with
        the acknowledged address in byte 5, and that is the default; AgIsoStack++'s client
        (at 509a920c) hears an acknowledgement from its TC only when addressed to it
        (``process_can_message_for_global_and_partner_callbacks``), so it never sees a global
        NACK and keeps sending after a TC restart shorter than its 6 s status timeout.
    usable : callable, optional
        ``usable(pool)`` raises a :class:`~hil.isobus.ddop.DdopError` (with the activate
        response's codes) for a valid pool this TC cannot work with; checked at activation.
    isolate_errors : bool
        End a client's session on an exception its messages or set-points raise, instead of
        raising it (see the module docstring).
    keep_records : bool
        Keep :attr:`values`, :attr:`acknowledgements` and :attr:`events` in memory (the
        ``recorder`` and :attr:`counts` get them either way).
    recorder : callable, optional
        Called with every record (event, value, acknowledgement) as it happens.
    checker : Executor, optional
        Parse and check received pools there (a thread) instead of on the network's thread.
    """

    def __init__(self, port: IsobusPort, *, options: ServerOptions | None = None,
                 store: PoolStore | None = None, setpoints: SetpointSource = no_setpoints,
                 triggers: TriggerPlan | None = None, setpoint_refresh_s: float | None = None,
                 on_value: Callable[[LoggedValue], None] | None = None,
                 language_command: bytes | None = DEFAULT_LANGUAGE_COMMAND,
                 nack_to_client: bool = False,
                 usable: Callable[[ObjectPool], None] | None = None,
                 isolate_errors: bool = False, keep_records: bool = True,
                 recorder: Callable[[Record], None] | None = None,
                 checker: Executor | None = None) -> None:
        if language_command is not None and len(language_command) != 8:
            raise ValueError(f"language command payload is {len(language_command)} bytes, not 8")
        self.port = port
        self.options = options or ServerOptions()
        self.store = store if store is not None else PoolStore()
        self.setpoints = setpoints
        self.triggers = triggers or TriggerPlan()
        self.setpoint_refresh_s = setpoint_refresh_s
        self.on_value = on_value
        self.language_command = language_command
        self.nack_to_client = nack_to_client
        self.usable = usable
        self.isolate_errors = isolate_errors
        self.keep_records = keep_records
        self.recorder = recorder
        self.checker = checker
        self.sessions: dict[int, ClientSession] = {}
        self.values: list[LoggedValue] = []
        self.acknowledgements: list[ReceivedAcknowledge] = []
        self.events: list[Event] = []
        #: how many values, acknowledgements and events were recorded (kept or not), and
        #: events by kind
        self.counts: Counter[str] = Counter()
        self.event_counts: Counter[EventKind] = Counter()
        self._unsolicited = RateLimiter(UNSOLICITED_PERIOD_S)
        #: the address the TC held at its last look (to see it lost)
        self._held: int | None = None
        self.status = pd.ServerStatus.NONE
        self._next_status_s: float | None = None
        self._last_status_s: float | None = None
        self._status_changed = False
        self._down_until_s: float | None = None
        self._now_s = 0.0
        #: when the next set-point round is due (every SETPOINT_PERIOD_S, absolute grid)
        self._next_setpoints_s: float | None = None
        port.subscribe(pd.PROCESS_DATA_PGN, self._on_process_data)
        port.subscribe(pd.WORKING_SET_MASTER_PGN, self._on_working_set_master)
        port.subscribe(REQUEST_PGN, self._on_request)
        port.subscribe(ADDRESS_CLAIMED_PGN, self._on_address_claim)

    # --- timers -----------------------------------------------------------------------------

    def tick(self, now_s: float) -> None:
        """Advance to ``now_s``: status when due, timeouts, triggers and set-points."""
        self._now_s = now_s
        self._watch_address(now_s)
        self._report_unsolicited(now_s)
        if self._down(now_s) or self.port.address is None:
            return
        for session in list(self.sessions.values()):
            if session.checking is not None and session.checking[0].done():
                self._guarded(session, now_s, self._finish_activation, session, now_s)
        changed = self._status_changed and (
            self._last_status_s is None or now_s - self._last_status_s >= MIN_STATUS_INTERVAL_S)
        periodic = self._next_status_s is not None and now_s >= self._next_status_s
        if changed or periodic or self._next_status_s is None:
            self._send(pd.TaskControllerStatus(self.status), GLOBAL_ADDRESS, PRIORITY_STATUS)
            self._status_changed = False
            self._last_status_s = now_s
            if periodic and not changed:
                # absolute deadlines: ticks that come late do not stretch the period
                assert self._next_status_s is not None
                while self._next_status_s <= now_s:
                    self._next_status_s += STATUS_PERIOD_S
            else:
                self._next_status_s = now_s + STATUS_PERIOD_S
        for address, session in list(self.sessions.items()):
            if now_s - session.last_seen_s >= CLIENT_TIMEOUT_S:
                del self.sessions[address]
                self._event(now_s, address, EventKind.TIMED_OUT,
                            f"no client task or working-set master for "
                            f"{now_s - session.last_seen_s:.1f} s")
                continue
            if session.pool is not None:
                self._guarded(session, now_s, self._send_triggers, session)
        if self._next_setpoints_s is None or now_s >= self._next_setpoints_s - 1e-9:
            for session in list(self.sessions.values()):
                self._guarded(session, now_s, self._send_setpoints, session, now_s)
            if self._next_setpoints_s is None:
                self._next_setpoints_s = now_s
            while self._next_setpoints_s <= now_s + 1e-9:
                self._next_setpoints_s += SETPOINT_PERIOD_S

    def next_due(self, now_s: float) -> float:
        """When the TC has something to do: its status (a changed one after the least
        interval), a client's timeout, triggers to send, the next set-point round."""
        if self.port.address != self._held:
            return now_s                  # the address changed: say so
        limiter = self._unsolicited.due()
        if self.port.address is None:
            # the network ticks it once the claim settles
            return max(now_s, limiter)
        if self._down(now_s):
            assert self._down_until_s is not None
            return max(now_s, min(self._down_until_s, limiter))
        due = now_s if self._next_status_s is None else self._next_status_s
        due = min(due, limiter)
        if self._status_changed:
            due = min(due, (self._last_status_s or -math.inf) + MIN_STATUS_INTERVAL_S)
        for session in self.sessions.values():
            due = min(due, session.last_seen_s + CLIENT_TIMEOUT_S)
            if session.checking is not None:
                due = min(due, now_s + CHECK_POLL_S)
            if session.pool is not None:
                due = min(due, now_s if session.triggers_due else
                          (self._next_setpoints_s if self._next_setpoints_s is not None
                           else now_s))
        return max(due, now_s)

    def restart(self, now_s: float, *, down_s: float = 0.0) -> None:
        """Restart the TC at ``now_s``: sessions are lost, stored pools kept.

        For ``down_s`` seconds the TC is silent and deaf (a reboot); then it sends its status
        again and every client must reconnect from its working-set master message.
        """
        self.sessions.clear()
        self.status = pd.ServerStatus.NONE
        self._next_status_s = None
        self._last_status_s = None
        self._status_changed = False
        self._down_until_s = now_s + down_s
        self._event(now_s, None, EventKind.SERVER_RESTARTED, f"down for {down_s:g} s")

    def come_back(self, now_s: float) -> None:
        """End a restart's down time at ``now_s`` (a reboot of unknown length, ended by the
        rig): the TC sends its status again from its next tick."""
        if self._down_until_s is not None and now_s < self._down_until_s:
            self._down_until_s = now_s

    def set_task_active(self, active: bool) -> None:
        """Start or stop the task: the status's task totals active bit, sent at the next tick
        (at most every 0.2 s), then every 2 s again from there."""
        status = self.status | pd.ServerStatus.TASK_TOTALS_ACTIVE if active else \
            self.status & ~pd.ServerStatus.TASK_TOTALS_ACTIVE
        if status != self.status:
            self.status = pd.ServerStatus(status)
            self._status_changed = True

    def _down(self, now_s: float) -> bool:
        return self._down_until_s is not None and now_s < self._down_until_s

    # --- sending ------------------------------------------------------------------------------

    def _send(self, message: pd.ProcessDataMessage, destination: int,
              priority: int = PRIORITY_DEFAULT) -> None:
        self.port.send(pd.PROCESS_DATA_PGN, pd.encode(message), destination, priority)

    def _event(self, time_s: float, address: int | None, kind: EventKind, detail: str = "",
               ) -> None:
        event = Event(time_s, address, kind, detail)
        self.counts["events"] += 1
        self.event_counts[kind] += 1
        if self.keep_records:
            self.events.append(event)
        if self.recorder is not None:
            self.recorder(event)

    def _reject(self, time_s: float, address: int, detail: str, *, nack: bool) -> None:
        """Log a rejected message (and NACK it) unless this address had one this period."""
        if not self._unsolicited.offer(address, time_s):
            return
        self._event(time_s, address, EventKind.REJECTED_MESSAGE, detail)
        if nack:
            self._nack(address)

    def _report_unsolicited(self, now_s: float) -> None:
        for address, count, since in self._unsolicited.ended(now_s):
            self._event(now_s, address, EventKind.REJECTED_MESSAGE,
                        f"{count} more message{'s' if count != 1 else ''} rejected since "
                        f"{since:.2f} s (counted, not logged one by one)")

    def _end_session(self, session: ClientSession, time_s: float, kind: EventKind,
                     detail: str) -> None:
        if self.sessions.get(session.address) is session:
            del self.sessions[session.address]
        if session.checking is not None:
            session.checking[0].cancel()
            session.checking = None
        self._event(time_s, session.address, kind, detail)

    def end_session(self, address: int, time_s: float, detail: str) -> None:
        """End the session at ``address`` for an error its client's data caused elsewhere (the
        rig's use of its pool): event ``client error``."""
        session = self.sessions.get(address)
        if session is not None:
            self._end_session(session, time_s, EventKind.CLIENT_ERROR, detail)

    def _guarded(self, session: ClientSession, time_s: float, step: Callable[..., None],
                 *args: object) -> None:
        """Run one step of a client's session; with ``isolate_errors`` an exception ends the
        session (named in the event) instead of the TC."""
        if not self.isolate_errors:
            step(*args)
            return
        try:
            step(*args)
        except Exception as exc:   # a client's input must not end the TC
            self._end_session(session, time_s, EventKind.CLIENT_ERROR,
                              f"{type(exc).__name__}: {exc}")

    def _nack(self, address: int) -> None:
        pgn = pd.PROCESS_DATA_PGN
        payload = bytes([0x01, 0xFF, 0xFF, 0xFF, address, pgn & 0xFF, (pgn >> 8) & 0xFF,
                         pgn >> 16])
        destination = address if self.nack_to_client else GLOBAL_ADDRESS
        self.port.send(ACKNOWLEDGEMENT_PGN, payload, destination, PRIORITY_DEFAULT)

    def _send_triggers(self, session: ClientSession) -> None:
        if not session.triggers_due or session.pool is None:
            return
        session.triggers_due = False
        for command in self.triggers.commands(session.pool):
            self._send(command, session.address)

    def _send_setpoints(self, session: ClientSession, now_s: float) -> None:
        pool = session.pool
        if pool is None:
            return
        for element_number, ddi_ in session.settable:
            value = self.setpoints(SetpointRequest(session.address, session.name,
                                                   element_number, ddi_, now_s))
            if value is None:
                continue
            _check_setpoint(element_number, ddi_, value)
            key = (element_number, ddi_)
            last = session.sent_setpoints.get(key)
            refresh = self.setpoint_refresh_s
            if last is not None and last[0] == value and (
                    refresh is None or now_s - last[1] < refresh):
                continue
            session.sent_setpoints[key] = (value, now_s)
            self._send(ElementCommand(Command.VALUE, element_number, ddi_, value),
                       session.address)

    # --- receiving ----------------------------------------------------------------------------

    def _key(self, address: int) -> tuple[ClientKey, int | None]:
        name = self.port.name_of(address)
        return (name if name is not None else ("address", address)), name

    def _on_working_set_master(self, msg: Received) -> None:
        if self._down(msg.time_s) or msg.source in (GLOBAL_ADDRESS, NULL_ADDRESS):
            return
        try:
            pd.decode_working_set_master(msg.data)
        except FrameError as exc:
            self._reject(msg.time_s, msg.source, str(exc), nack=False)
            return
        session = self.sessions.get(msg.source)
        if session is not None:
            session.last_seen_s = msg.time_s
            return
        key, name = self._key(msg.source)
        if name is None:
            # ISO 11783-5: a control function claims its address before anything else; a
            # session belongs to a NAME, and this address has none the TC heard (it may have
            # claimed before the TC was on the bus): ask it for its claim (at the limiter's
            # rate), and let it connect again
            if self._unsolicited.offer(msg.source, msg.time_s):
                self._event(msg.time_s, msg.source, EventKind.REJECTED_MESSAGE,
                            "working-set master from an address whose claim the TC has not "
                            "heard: no session; its claim is requested")
                self._request_claims(msg.source)
            return
        self.sessions[msg.source] = ClientSession(msg.source, key, name, msg.time_s, msg.time_s)
        self._event(msg.time_s, msg.source, EventKind.CONNECTED, f"NAME {name:016X}")

    def _on_address_claim(self, msg: Received) -> None:
        """A claim seen on the bus: a session whose address changed hands, or whose NAME moved
        (or could not claim), ends; so do they all when the TC lost its own address."""
        if len(msg.data) != 8:
            return
        claimant = int.from_bytes(msg.data, "little")
        holder = self.port.name_of(msg.source) if msg.source != NULL_ADDRESS else None
        for session in list(self.sessions.values()):
            if session.address == msg.source and holder != session.name:
                self._end_session(session, msg.time_s, EventKind.SESSION_ENDED,
                                  f"NAME {claimant:016X} claimed 0x{msg.source:02X}, the "
                                  f"address of NAME {session.name or 0:016X}: the session was "
                                  f"that NAME's")
            elif session.name == claimant and session.address != msg.source:
                where = ("could not claim an address" if msg.source == NULL_ADDRESS
                         else f"moved to 0x{msg.source:02X}")
                self._end_session(session, msg.time_s, EventKind.SESSION_ENDED,
                                  f"the client's NAME {claimant:016X} {where}")
        self._watch_address(msg.time_s, claimant if msg.source == self._held else None)

    def _watch_address(self, now_s: float, claimant: int | None = None) -> None:
        """Say when the TC's own address is lost or held again; a lost one ends every
        session (clients find the TC again by its status, from wherever it is)."""
        address = self.port.address
        if address == self._held:
            return
        if self._held is not None:
            for session in list(self.sessions.values()):
                self._end_session(session, now_s, EventKind.SESSION_ENDED,
                                  f"the TC no longer holds its address 0x{self._held:02X}")
            if claimant is not None:
                self._event(now_s, None, EventKind.ADDRESS_LOST,
                            f"the TC lost 0x{self._held:02X} to NAME {claimant:016X} (a lower "
                            f"NAME wins, ISO 11783-5); " + (
                                "it claims another" if address is None
                                else f"it holds 0x{address:02X}"))
            # else its own claim started again (a power cycle): no one took the address
            self._next_status_s = None      # its status goes out at once from the new one
        self._held = address
        if address is not None:
            self._event(now_s, None, EventKind.ADDRESS_CLAIMED, f"the TC holds 0x{address:02X}")
            # clients that claimed before the TC was on the bus: their claims, so that their
            # sessions have a NAME (ISO 11783-5 lets any control function ask)
            self._request_claims(GLOBAL_ADDRESS)

    def _request_claims(self, destination: int) -> None:
        self.port.send(REQUEST_PGN, ADDRESS_CLAIMED_PGN.to_bytes(3, "little"), destination,
                       PRIORITY_DEFAULT + 1)

    def _on_request(self, msg: Received) -> None:
        if self._down(msg.time_s) or len(msg.data) < 3 or self.language_command is None:
            return
        if int.from_bytes(msg.data[:3], "little") == LANGUAGE_COMMAND_PGN:
            self.port.send(LANGUAGE_COMMAND_PGN, self.language_command, GLOBAL_ADDRESS,
                           PRIORITY_DEFAULT)

    def _on_process_data(self, msg: Received) -> None:
        if self._down(msg.time_s) or msg.source in (GLOBAL_ADDRESS, NULL_ADDRESS):
            return
        try:
            message = pd.decode(msg.data)
        except FrameError as exc:
            self._reject(msg.time_s, msg.source, str(exc), nack=False)
            return
        session = self.sessions.get(msg.source)
        if session is None:
            if not isinstance(message, pd.ClientTask | pd.TaskControllerStatus):
                self._reject(msg.time_s, msg.source, f"{type(message).__name__} before a "
                             f"working-set master message", nack=True)
            return
        self._guarded(session, msg.time_s, self._handle, session, message, msg)

    def _handle(self, session: ClientSession, message: pd.ProcessDataMessage,
                msg: Received) -> None:
        t = msg.time_s
        match message:
            case pd.ClientTask():
                session.last_seen_s = t
                session.task_active = message.task_active
            case pd.RequestVersion():
                self._send(pd.Version(self.options.version, self.options.options,
                                      self.options.booms, self.options.sections,
                                      self.options.channels), session.address)
                if session.version is None and not session.version_asked:
                    # ISO 11783-10: the client asks first; the TC asks back once answered
                    session.version_asked = True
                    self._send(pd.RequestVersion(), session.address)
            case pd.Version():
                session.version = message.version
                self._event(t, session.address, EventKind.VERSION,
                            f"version {message.version}, options 0x{message.options:02X}")
            case pd.RequestStructureLabel():
                if message.label == pd.LABEL_NONE:
                    stored = self.store.latest(session.key)
                else:
                    stored = self.store.by_structure(session.key, message.label,
                                                     message.extended)
                self._send(pd.StructureLabel(stored.structure_label,
                                             stored.extended_structure_label)
                           if stored else pd.StructureLabel(), session.address)
            case pd.RequestLocalizationLabel():
                if message.label == pd.LABEL_NONE:
                    stored = self.store.latest(session.key)
                else:
                    stored = self.store.by_localization(session.key, message.label)
                self._send(pd.LocalizationLabel(stored.localization_label) if stored
                           else pd.LocalizationLabel(), session.address)
            case pd.RequestObjectPoolTransfer():
                enough = message.size <= self.options.memory_bytes
                if enough:
                    session.announced_size = message.size
                    session.transfer.clear()
                else:
                    self._event(t, session.address, EventKind.REFUSED,
                                f"not enough memory: a pool of {message.size} bytes, room for "
                                f"{self.options.memory_bytes}")
                self._send(pd.RequestObjectPoolTransferResponse(enough), session.address)
            case pd.ObjectPoolTransfer():
                if len(session.transfer) + len(message.pool) > self.options.memory_bytes:
                    self._send(pd.ObjectPoolTransferResponse(0x01, len(message.pool)),
                               session.address)
                    return
                session.transfer += message.pool
                self._event(t, session.address, EventKind.POOL_TRANSFERRED,
                            f"{len(message.pool)} bytes ({len(session.transfer)} in all)")
                self._send(pd.ObjectPoolTransferResponse(0, len(message.pool)), session.address)
            case pd.ObjectPoolActivate(activate=True):
                self._activate(session, t)
            case pd.ObjectPoolActivate(activate=False):
                session.pool = None
                session.sent_setpoints.clear()
                self._event(t, session.address, EventKind.DEACTIVATED)
                self._send(pd.ObjectPoolActivateResponse(0), session.address)
            case pd.DeleteObjectPool():
                self.store.delete(session.key)
                session.transfer.clear()
                self._event(t, session.address, EventKind.DELETED)
                self._send(pd.DeleteObjectPoolResponse(True), session.address)
            case ElementCommand(command=Command.VALUE | Command.SET_VALUE_AND_ACKNOWLEDGE):
                self._on_value(session, message, t)
            case ElementCommand():
                # Request value and measurement commands are the TC's to send, not a client's.
                self._send(pd.ProcessDataAcknowledge(message.element, message.ddi,
                                                     AckError.COMMAND_NOT_SUPPORTED,
                                                     message.command),
                           session.address, PRIORITY_ACK)
            case pd.ProcessDataAcknowledge():
                ack = ReceivedAcknowledge(t, session.address, message.element, message.ddi,
                                          int(message.errors), message.command)
                self.counts["acknowledgements"] += 1
                if self.keep_records:
                    self.acknowledgements.append(ack)
                if self.recorder is not None:
                    self.recorder(ack)
            case _:
                self._reject(t, session.address,
                             f"{type(message).__name__} is not a client's message", nack=False)

    def _on_value(self, session: ClientSession, message: ElementCommand, t: float) -> None:
        errors = AckError.NONE
        pool = session.pool
        if pool is None:
            errors = AckError.COMMAND_NOT_SUPPORTED
        elif pool.element(message.element) is None:
            errors = AckError.INVALID_ELEMENT_NUMBER
        elif pool.process_data(message.element, message.ddi) is None:
            errors = AckError.DDI_NOT_SUPPORTED_BY_ELEMENT
        if not errors:
            logged = LoggedValue(t, session.address, message.element, message.ddi,
                                 message.value)
            self.counts["values"] += 1
            if self.keep_records:
                self.values.append(logged)
            if self.recorder is not None:
                self.recorder(logged)
            if self.on_value is not None:
                self.on_value(logged)
        if errors or message.command == Command.SET_VALUE_AND_ACKNOWLEDGE:
            self._send(pd.ProcessDataAcknowledge(message.element, message.ddi, errors,
                                                 message.command), session.address, PRIORITY_ACK)

    def _activate(self, session: ClientSession, t: float) -> None:
        if session.checking is not None:
            return      # a check is under way: its answer is the response
        raw = bytes(session.transfer)
        version = session.version if session.version is not None else self.options.version
        version = min(version, self.options.version)
        if raw and self.checker is not None:
            session.checking = (self.checker.submit(parse_and_check, raw, version, self.usable),
                                raw)
            return
        try:
            pool = parse_and_check(raw, version, self.usable) if raw else None
        except DdopError as err:
            self._refuse_pool(session, t, err)
            return
        self._complete_activation(session, t, pool, raw)

    def _finish_activation(self, session: ClientSession, t: float) -> None:
        """The check off the network's thread is done: answer the activation."""
        assert session.checking is not None
        future, raw = session.checking
        session.checking = None
        try:
            pool = future.result()
        except DdopError as err:
            self._refuse_pool(session, t, err)
            return
        self._complete_activation(session, t, pool, raw)

    def _refuse_pool(self, session: ClientSession, t: float, err: DdopError) -> None:
        self._event(t, session.address, EventKind.REFUSED, str(err))
        self._send(pd.ObjectPoolActivateResponse(
            int(err.activation_error),
            err.parent_id if err.parent_id is not None else 0xFFFF,
            err.object_id if err.object_id is not None else 0xFFFF,
            int(err.pool_error)), session.address)

    def _complete_activation(self, session: ClientSession, t: float, pool: ObjectPool | None,
                             raw: bytes) -> None:
        try:
            if pool is None:
                stored = self.store.latest(session.key)
                if stored is None:
                    raise DdopError(
                        "no pool was transferred and none is stored for this client",
                        object_id=None, activation_error=ActivationError.ANY_OTHER_ERROR,
                        pool_error=PoolError.NONE)
                pool, raw = stored.pool, stored.raw
            device = pool.device
            if session.name is not None and device.name != session.name:
                raise DdopError(f"the device object's NAME {device.name:016X} is not the "
                                f"client's {session.name:016X}", object_id=device.object_id)
            same_label = self.store.by_structure(session.key, device.structure_label,
                                                 device.extended_structure_label)
            if same_label is not None and same_label.raw != raw:
                raise DdopError(
                    "a different pool with the same structure label is stored; change the "
                    "structure label or delete the stored pool", object_id=device.object_id,
                    activation_error=ActivationError.DIFFERENT_DDOP_SAME_STRUCTURE_LABEL,
                    pool_error=PoolError.NONE)
        except DdopError as err:
            self._refuse_pool(session, t, err)
            return
        session.pool = pool
        session.settable = pool.settable()
        session.pool_raw = raw
        session.transfer.clear()
        session.triggers_due = True
        session.sent_setpoints.clear()
        self.store.put(session.key, pool, raw)
        self._event(t, session.address, EventKind.ACTIVATED,
                    f"{len(pool.objects)} objects, {len(raw)} bytes, version {pool.version}")
        self._send(pd.ObjectPoolActivateResponse(0), session.address)


def parse_and_check(raw: bytes, version: int,
                    usable: Callable[[ObjectPool], None] | None = None) -> ObjectPool:
    """Parse ``raw``, validate it by ISO 11783-10's rules, and check that this TC can use it
    (run on the network's thread, or in the server's ``checker``).

    Raises
    ------
    DdopError
        The first problem, with the activate response's codes.
    """
    pool = ObjectPool.from_bytes(raw, version=version)
    if usable is not None:
        usable(pool)
    return pool

