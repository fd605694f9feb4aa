"""The Virtual Terminal server (ISO 11783-6, versions 3 to 6, 4 by default) on an ISOBUS port.

:class:`VirtualTerminalServer` is an application of the network layer like the Task Controller
(:mod:`hil.isobus.tc.server`): no thread, no clock; the network ticks it with the run time, so
it runs in lockstep and in real time alike. What a working set sees:

- the VT status message every second (function 0xFE: the active working set master's address,
  its data mask and soft key mask);
- its working set maintenance messages watched: a working set silent for 3 s is gone (its
  pool leaves the VT's volatile memory; stored versions stay);
- the connection procedure answered: get memory, get number of soft keys, get text font data,
  get hardware, get supported objects, get window mask data, get versions and extended get
  versions; store, load and delete version (extended too) against a
  :class:`~hil.isobus.vt.store.VersionStore` that outlives a VT restart, so a second
  connection loads its pool instead of uploading it;
- object pool transfers (whole parameter groups: the network layer brings them by TP or ETP),
  several before the end of object pool message; then the pool parsed and validated
  (:class:`~hil.isobus.vt.pool.ObjectPool`), and the end of object pool response with the
  standard's error codes and the faulty object's id when it is refused;
- its commands applied to its pool and answered (:mod:`hil.isobus.vt.commands`), each one
  recorded in :attr:`VirtualTerminalServer.commands`;
- a function the VT does not have answered with "unsupported VT function" (0xFD, version 5 and
  later) or a negative acknowledgement (versions 3 and 4).

The operator's side (soft keys, buttons, numeric and string input) is :meth:`key_event`,
:meth:`enter_number`, :meth:`enter_string` and :meth:`escape`; :mod:`hil.isobus.vt.operator`
scripts them in time. Whatever may change what the operator sees calls the ``on_change``
hooks (the renderer and the browser VT listen there).
"""

from __future__ import annotations

import heapq
import queue
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.port import GLOBAL_ADDRESS, NULL_ADDRESS, IsobusPort, Received
from hil.isobus.tc.limiter import RateLimiter
from hil.isobus.vt.bounded import BoundedLog
from hil.isobus.vt.codec import VtObject
from hil.isobus.vt.commands import apply, is_enabled
from hil.isobus.vt.errors import NO_OBJECT, EndOfPoolError, PoolErrorCode, VtPoolError
from hil.isobus.vt.layouts import INTRODUCED_IN, ObjectType
from hil.isobus.vt.messages import (
    ACKNOWLEDGEMENT_PGN,
    ECU_TO_VT_PGN,
    EXTENDED_LABEL_LENGTH,
    LABEL_LENGTH,
    VT_TO_ECU_PGN,
    WORKING_SET_MASTER_PGN,
    Function,
    KeyActivation,
    get32,
    pad,
    u16,
    u32,
)
from hil.isobus.vt.pool import ObjectPool
from hil.isobus.vt.store import ClientKey, StoreError, StoreFull, StoreLimits, VersionStore
from hil.isobus.vt.workingset import INPUTS, WorkingSet

T = ObjectType

STATUS_PERIOD_S = 1.0
"""The VT status period (ISO 11783-6)."""
WORKING_SET_TIMEOUT_S = 3.0
"""A working set silent this long (no maintenance message) is gone."""
INBOX_POLL_S = 0.05
"""How often the VT looks for actions posted from another thread, once there have been any."""
KEY_REPEAT_S = 0.2
"""How often a held soft key or button is reported as still held."""
PRIORITY = 5
REQUEST_PGN = 0xEA00
ADDRESS_CLAIMED_PGN = 0xEE00
UNSOLICITED_PERIOD_S = 1.0
"""Messages from an address the VT serves no working set for: one logged (and its claim asked
for) per address and period, the rest counted."""
EVENTS_KEPT = 2_000
"""Events kept in memory (the first quarter and the latest; :class:`BoundedLog`)."""
COMMANDS_KEPT = 5_000
"""Command records kept in memory (:attr:`VirtualTerminalServer.counts` has them all)."""
RESPONSES_KEPT = 1_000
"""Working set responses kept in memory."""
ACTIVATIONS_KEPT = 256
"""Pool activations kept in memory."""


@dataclass(frozen=True)
class VtOptions:
    """What the VT is and reports.

    Attributes
    ----------
    version : int
        VT version, 3 to 6 (the get memory response and the object types it takes).
    memory_bytes : int
        Object pool memory: get memory answers "not enough" beyond it, a transfer beyond it
        ends in "out of memory".
    data_mask_px : int
        Width and height of the (square) data mask area, pixels.
    soft_key_width_px, soft_key_height_px : int
        A soft key descriptor's size, pixels.
    virtual_soft_keys, physical_soft_keys, navigation_soft_keys : int
        Soft keys per soft key mask, physical keys, navigation keys.
    small_fonts, large_fonts, font_styles : int
        The get text font data bit fields (all sizes; normal style only: the rig draws no
        bold, italic or flashing text).
    store_max_bytes, store_max_versions, store_max_versions_per_name : int
        What the version store keeps at most (:class:`~hil.isobus.vt.store.StoreLimits`): a
        store version beyond them is answered "insufficient memory" (error bit 2).

    ``memory_bytes`` is the VT's whole pool memory: the working sets connected at once share
    it (get memory answers with what the others leave free).
    """

    version: int = 4
    memory_bytes: int = 4 * 1024 * 1024
    data_mask_px: int = 480
    soft_key_width_px: int = 80
    soft_key_height_px: int = 60
    virtual_soft_keys: int = 6
    physical_soft_keys: int = 6
    navigation_soft_keys: int = 0
    small_fonts: int = 0xFF
    large_fonts: int = 0x7F
    font_styles: int = 0x00
    store_max_bytes: int = StoreLimits.max_bytes
    store_max_versions: int = StoreLimits.max_versions
    store_max_versions_per_name: int = StoreLimits.max_versions_per_name

    @property
    def store_limits(self) -> StoreLimits:
        """The version store's bounds."""
        return StoreLimits(self.store_max_bytes, self.store_max_versions,
                           self.store_max_versions_per_name)

    def __post_init__(self) -> None:
        if self.version not in (3, 4, 5, 6):
            raise ValueError(f"VT version {self.version}: the rig's VT is version 3, 4, 5 or 6")
        if not 200 <= self.data_mask_px <= 65535:
            raise ValueError(f"data mask of {self.data_mask_px} px: at least 200 (the "
                             f"standard's smallest VT)")
        if self.memory_bytes <= 0:
            raise ValueError(f"VT memory of {self.memory_bytes} bytes")
        self.store_limits    # noqa: B018  (checks the bounds)


@dataclass(frozen=True)
class VtEvent:
    """A connection event: connected, memory, transferred, activated, refused, loaded,
    stored, deleted, timed out, restarted, operator."""

    time_s: float
    address: int | None
    kind: str
    detail: str = ""


@dataclass(frozen=True)
class VtCommandRecord:
    """One command a working set sent and how the VT answered it."""

    time_s: float
    address: int
    function: int
    object_id: int
    error: int
    detail: str


@dataclass
class PoolActivation:
    """A pool that became active: what the run's record keeps of it."""

    time_s: float
    address: int
    name: int | None
    pool_bytes: int
    objects: int
    vt_version: int
    transfers: int
    sha256: str
    object_types: dict[str, int]
    version_label: str | None
    loaded_from_storage: bool


ChangeHook = Callable[[WorkingSet, float, str], None]


@dataclass(order=True)
class _Timer:
    time_s: float
    seq: int
    action: Callable[[float], None] = field(compare=False)


class VirtualTerminalServer:
    """A VT on an ISOBUS port (see the module docstring).

    Parameters
    ----------
    port : IsobusPort
        The network seam.
    options : VtOptions
        Version, memory, screen.
    store : VersionStore, optional
        Stored versions; pass the same store to a restarted VT.
    """

    def __init__(self, port: IsobusPort, options: VtOptions | None = None,
                 store: VersionStore | None = None) -> None:
        self.port = port
        self.options = options or VtOptions()
        self.store = store if store is not None else VersionStore()
        self.sessions: dict[int, WorkingSet] = {}
        #: connection events (the first and the latest :data:`EVENTS_KEPT`)
        self.events: BoundedLog[VtEvent] = BoundedLog(EVENTS_KEPT)
        self.commands: BoundedLog[VtCommandRecord] = BoundedLog(COMMANDS_KEPT)
        #: (time, address, data) of the working sets' responses to the VT's own messages
        self.responses: BoundedLog[tuple[float, int, bytes]] = BoundedLog(RESPONSES_KEPT)
        #: the pools that became active, in order (kept when their working set leaves)
        self.activations: BoundedLog[PoolActivation] = BoundedLog(ACTIVATIONS_KEPT)
        #: everything counted, kept in memory or not: ``events``, ``commands``,
        #: ``command errors``, ``responses``, ``rejected``, and events by ``event <kind>``
        self.counts: Counter[str] = Counter()
        self.on_change: list[ChangeHook] = []
        self.last_function = 0xFF
        self._next_status_s: float | None = None
        self._down_until_s: float | None = None
        self._timers: list[_Timer] = []
        self._seq = 0
        self._now = 0.0
        #: actions posted from other threads (the browser VT), run at the next tick
        self._inbox: queue.SimpleQueue[Callable[[float], None]] | None = None
        self._claims_requested = False
        #: messages from addresses without a working set: logged and answered at a bounded rate
        self._unsolicited = RateLimiter(UNSOLICITED_PERIOD_S)
        #: commands before a pool: NACKed at the same bounded rate
        self._early_commands = RateLimiter(UNSOLICITED_PERIOD_S)
        #: working sets whose transfers ran past the VT's memory (refused at end of pool)
        self._overflowed: set[int] = set()
        #: the address the VT held at its last look (to see it lost)
        self._held: int | None = None
        port.subscribe(ECU_TO_VT_PGN, self._on_message)
        port.subscribe(WORKING_SET_MASTER_PGN, self._on_working_set_master)
        port.subscribe(ADDRESS_CLAIMED_PGN, self._on_address_claim)

    # -- timers ----------------------------------------------------------------------------------

    def tick(self, now_s: float) -> None:
        """Advance to ``now_s``: status, working set timeouts, lock timeouts, operator timers."""
        self._now = now_s
        self._watch_address(now_s)
        self._report_unsolicited(now_s)
        if self._down(now_s) or self.port.address is None:
            return
        if self._inbox is not None:
            while not self._inbox.empty():
                self._inbox.get_nowait()(now_s)
        if not self._claims_requested:
            # working sets that claimed before the VT was on the bus: their claims, so that
            # their transfers are answered and their versions kept under their NAMEs
            self._claims_requested = True
            self._request_claims(GLOBAL_ADDRESS)
        while self._timers and self._timers[0].time_s <= now_s + 1e-9:
            timer = heapq.heappop(self._timers)
            try:
                timer.action(now_s)
            except Exception as exc:    # a drawing of a client's pool must not end the VT
                self._event(now_s, None, "error", f"a timed action raised "
                            f"{type(exc).__name__}: {exc}")
        if self._next_status_s is None or now_s >= self._next_status_s - 1e-9:
            self._send_status()
            if self._next_status_s is None:
                self._next_status_s = now_s
            while self._next_status_s <= now_s + 1e-9:
                self._next_status_s += STATUS_PERIOD_S
        for address, ws in list(self.sessions.items()):
            if not self._still_its_names(ws, now_s):
                continue
            if now_s - ws.last_seen_s >= WORKING_SET_TIMEOUT_S - 1e-9:
                self._end(ws, now_s, "timed out",
                          f"no working set maintenance for {now_s - ws.last_seen_s:.1f} s")
                continue
            if ws.lock_until_s is not None and now_s >= ws.lock_until_s - 1e-9:
                mask = ws.locked_mask
                ws.locked_mask = ws.lock_until_s = None
                self._send(ws.address, pad([Function.LOCK_UNLOCK_MASK, 0, 0x10]))
                self._event(now_s, address, "unlocked", f"mask {mask}: lock timed out")
                self._changed(ws, now_s, "unlock")

    def next_due(self, now_s: float) -> float:
        """When the VT has something to do."""
        if self.port.address != self._held:
            return now_s                  # the address changed: say so
        limiter = self._unsolicited.due()
        if self.port.address is None:
            return max(now_s, limiter)
        if self._down(now_s):
            assert self._down_until_s is not None
            return max(now_s, min(self._down_until_s, limiter))
        due = now_s if self._next_status_s is None else self._next_status_s
        due = min(due, limiter)
        if self._timers:
            due = min(due, self._timers[0].time_s)
        if self._inbox is not None:
            due = min(due, now_s + INBOX_POLL_S)
        for ws in self.sessions.values():
            due = min(due, ws.last_seen_s + WORKING_SET_TIMEOUT_S)
            if ws.lock_until_s is not None:
                due = min(due, ws.lock_until_s)
        return max(due, now_s)

    def at(self, time_s: float, action: Callable[[float], None]) -> None:
        """Run ``action(now)`` at run time ``time_s`` (the scripted operator's timeline)."""
        self._seq += 1
        heapq.heappush(self._timers, _Timer(time_s, self._seq, action))

    def post(self, action: Callable[[float], None]) -> None:
        """Run ``action(now)`` at the VT's next tick; safe from any thread (the browser VT
        posts the operator's presses here). Once used, the VT polls every 50 ms."""
        if self._inbox is None:
            self._inbox = queue.SimpleQueue()
        self._inbox.put(action)

    def restart(self, now_s: float, *, down_s: float = 0.0) -> None:
        """Restart the VT: working sets and their pools lost, stored versions kept; silent for
        ``down_s`` seconds, then the status again."""
        for ws in list(self.sessions.values()):
            self._changed(ws, now_s, "VT restarted")
        self.sessions.clear()
        self._overflowed.clear()
        self._next_status_s = None
        self._timers.clear()
        self._claims_requested = False
        self._down_until_s = now_s + down_s
        self._event(now_s, None, "restarted", f"down for {down_s:g} s")

    def _down(self, now_s: float) -> bool:
        return self._down_until_s is not None and now_s < self._down_until_s

    # -- what the VT shows -----------------------------------------------------------------------

    @property
    def active_working_set(self) -> WorkingSet | None:
        """The working set whose masks the VT shows: the first with an active pool."""
        for ws in list(self.sessions.values()):    # a copy: the browser VT asks from its thread
            if ws.active:
                return ws
        return None

    def _send_status(self) -> None:
        ws = self.active_working_set
        address = ws.address if ws is not None else 0xFE
        mask = ws.active_mask if ws is not None else NO_OBJECT
        keys = ws.soft_key_mask if ws is not None else NO_OBJECT
        self.port.send(VT_TO_ECU_PGN, bytes([Function.VT_STATUS, address]) + u16(mask)
                       + u16(keys) + bytes([0, self.last_function]), GLOBAL_ADDRESS, PRIORITY)

    # -- helpers ---------------------------------------------------------------------------------

    def _send(self, address: int, data: bytes) -> None:
        self.port.send(VT_TO_ECU_PGN, data, address, PRIORITY)

    def _event(self, time_s: float, address: int | None, kind: str, detail: str = "") -> None:
        self.counts["events"] += 1
        self.counts[f"event {kind}"] += 1
        self.events.append(VtEvent(time_s, address, kind, detail))

    def _changed(self, ws: WorkingSet, time_s: float, reason: str, *,
                 quiet: bool = False) -> None:
        for hook in list(self.on_change):
            try:
                hook(ws, time_s, reason)
            except Exception as exc:    # drawing a client's pool must not end the VT
                if not quiet:
                    self._client_error(ws, time_s, exc, "drawing its screen")

    def _client_error(self, ws: WorkingSet, time_s: float, exc: Exception, doing: str) -> None:
        """An exception a working set's input raised: its working set ends, the VT goes on."""
        detail = f"{doing}: {type(exc).__name__}: {exc}"
        if self.sessions.get(ws.address) is ws:
            self._end(ws, time_s, "client error", detail)
        else:
            self._event(time_s, ws.address, "client error", detail)

    def _end(self, ws: WorkingSet, time_s: float, kind: str, detail: str) -> None:
        """End a working set: its pool leaves the VT's volatile memory (stored versions stay)."""
        if self.sessions.get(ws.address) is ws:
            del self.sessions[ws.address]
        self._overflowed.discard(ws.address)
        ws.transfers.clear()
        self._event(time_s, ws.address, kind, detail)
        # a working set ended for an error is not reported again if its drawing fails again
        self._changed(ws, time_s, "working set gone", quiet=kind == "client error")

    def _reject(self, time_s: float, address: int, detail: str) -> None:
        """A message from an address the VT serves no working set for: logged, and its claim
        asked for, once per address and period; the rest counted."""
        self.counts["rejected"] += 1
        if address in (GLOBAL_ADDRESS, NULL_ADDRESS) or \
                not self._unsolicited.offer(address, time_s):
            return
        self._event(time_s, address, "rejected message", detail)
        self._request_claims(address)

    def _report_unsolicited(self, now_s: float) -> None:
        for address, count, since in self._unsolicited.ended(now_s):
            self._event(now_s, address, "rejected message",
                        f"{count} more message{'s' if count != 1 else ''} since {since:.2f} s "
                        f"(counted, not logged one by one)")

    def _on_address_claim(self, msg: Received) -> None:
        """A claim on the bus: a working set whose address changed hands, or whose NAME moved
        (or could not claim), ends; every one ends when the VT lost its own address."""
        if len(msg.data) != 8:
            return
        claimant = int.from_bytes(msg.data, "little")
        holder = self.port.name_of(msg.source) if msg.source != NULL_ADDRESS else None
        for ws in list(self.sessions.values()):
            if ws.address == msg.source and holder != ws.name:
                self._end(ws, msg.time_s, "session ended",
                          f"NAME {claimant:016X} claimed 0x{msg.source:02X}, the address of "
                          f"NAME {ws.name or 0:016X}: the working set was that NAME's")
            elif ws.name == claimant and ws.address != msg.source:
                where = ("could not claim an address" if msg.source == NULL_ADDRESS
                         else f"moved to 0x{msg.source:02X}")
                self._end(ws, msg.time_s, "session ended",
                          f"the working set's NAME {claimant:016X} {where}")
        self._watch_address(msg.time_s, claimant if msg.source == self._held else None)

    def _watch_address(self, now_s: float, claimant: int | None = None) -> None:
        """Say when the VT lost its address (a lower NAME claimed it: the VT yields, as ISO
        11783-5 says, and its working sets end) or holds one again."""
        address = self.port.address
        if address == self._held:
            return
        if self._held is not None:
            for ws in list(self.sessions.values()):
                self._end(ws, now_s, "session ended",
                          f"the VT no longer holds its address 0x{self._held:02X}")
            self._event(now_s, None, "address lost",
                        f"the VT lost 0x{self._held:02X}"
                        + (f" to NAME {claimant:016X} (a lower NAME wins, ISO 11783-5)"
                           if claimant is not None else "")
                        + ("; it holds no address (its NAME is not self-configurable)"
                           if address is None else f"; it holds 0x{address:02X}"))
            self._next_status_s = None
            self._claims_requested = False
        elif address is not None and self.counts["event address lost"]:
            self._event(now_s, None, "address claimed", f"the VT holds 0x{address:02X}")
        self._held = address

    def _key(self, address: int) -> tuple[ClientKey, int | None]:
        name = self.port.name_of(address)
        return (name if name is not None else ("address", address)), name

    def _request_claims(self, destination: int) -> None:
        self.port.send(REQUEST_PGN, ADDRESS_CLAIMED_PGN.to_bytes(3, "little"), destination,
                       PRIORITY + 1)

    def _still_its_names(self, ws: WorkingSet, time_s: float) -> bool:
        """Whether the working set's NAME still holds its address in the network's table; one
        whose NAME left it ends here. The claims that move a NAME are watched as they come
        (:meth:`_on_address_claim`), but not every one reaches the VT: a claim of the VT's
        own address is the network's to answer (found by the peer-side fuzzing: a working
        set's NAME claiming 0x26 left the working set at its old address)."""
        if ws.name is None or self.port.name_of(ws.address) == ws.name:
            return True
        self._end(ws, time_s, "session ended",
                  f"the working set's NAME {ws.name:016X} no longer holds 0x{ws.address:02X}")
        return False

    def _session(self, address: int, time_s: float, why: str) -> WorkingSet | None:
        """The working set at ``address``, started when the address's NAME is known; ``None``
        (the message rejected, the address's claim asked for) when it is not: a working set
        belongs to a NAME (ISO 11783-5: a control function claims before anything else)."""
        ws = self.sessions.get(address)
        if ws is not None and self._still_its_names(ws, time_s):
            return ws
        key, name = self._key(address)
        if name is None or address in (GLOBAL_ADDRESS, NULL_ADDRESS):
            self._reject(time_s, address, f"{why} from an address whose claim the VT has not "
                         f"heard: no working set; its claim is requested")
            return None
        ws = WorkingSet(address, key, name, time_s, time_s)
        self.sessions[address] = ws
        self._event(time_s, address, "connected", f"NAME {name:016X} ({why})")
        return ws

    # -- receiving -------------------------------------------------------------------------------

    def _on_working_set_master(self, msg: Received) -> None:
        if self._down(msg.time_s) or msg.destination not in (GLOBAL_ADDRESS,
                                                             self.port.address):
            return
        ws = self._session(msg.source, msg.time_s, "working set master")
        if ws is not None:
            ws.last_seen_s = msg.time_s

    def _on_message(self, msg: Received) -> None:
        t = msg.time_s
        self._now = max(self._now, t)
        if self._down(t) or not msg.data or msg.destination != self.port.address:
            return
        d = msg.data
        function = d[0]
        if len(d) < 8 and function != Function.OBJECT_POOL_TRANSFER:
            d = pad(d)        # a single frame is 8 bytes: a shorter one is read as padded
        known = msg.source in self.sessions
        ws = self._session(msg.source, t, f"function 0x{function:02X}")
        if ws is None:
            return
        if not known and function != Function.WORKING_SET_MAINTENANCE:
            self._event(t, msg.source, "out of order",
                        f"function 0x{function:02X} before a working set master or "
                        f"maintenance message")
        ws.last_seen_s = t
        try:
            self._handle(ws, function, d, t)
        except Exception as exc:    # no working set's input may end the VT (or the serve)
            self._client_error(ws, t, exc, f"function 0x{function:02X}")

    def _handle(self, ws: WorkingSet, function: int, d: bytes, t: float) -> None:
        """One message of a working set the VT serves."""
        if function == Function.WORKING_SET_MAINTENANCE:
            if ws.maintenance_s is None or d[1] & 0x01:
                ws.version = d[2] if len(d) > 2 and d[2] != 0xFF else None
            ws.maintenance_s = t
            return
        if function in _RESPONSES:
            # the working set's response to a message the VT sent (a soft key or button
            # activation, a numeric or string value the operator entered): kept, not answered
            self.counts["responses"] += 1
            self.responses.append((t, ws.address, bytes(d)[:64]))
            return
        self.last_function = function
        handler = self._STATELESS.get(function)
        if handler is not None:
            handler(self, ws, d, t)
            return
        result = apply(ws, d, t) if ws.pool is not None else None
        if result is None:
            if ws.pool is None and function in _COMMAND_FUNCTIONS:
                self._refuse(ws, function, t, "command before a pool is active")
            else:
                self._refuse(ws, function, t, f"function 0x{function:02X} is not supported",
                             unsupported=True)
            return
        if result.response is not None:
            self._send(ws.address, result.response)
        self._record(ws, t, result.function, result.object_id, result.error, result.detail)
        if result.changed and ws.locked_mask is None:
            self._changed(ws, t, result.detail)

    def _record(self, ws: WorkingSet, t: float, function: int, object_id: int, error: int,
                detail: str) -> None:
        self.counts["commands"] += 1
        if error:
            self.counts["command errors"] += 1
        self.commands.append(VtCommandRecord(t, ws.address, function, object_id, error,
                                             detail))

    def _refuse(self, ws: WorkingSet, function: int, t: float, why: str,
                unsupported: bool = False) -> None:
        """A function the VT does not have ("unsupported VT function", 0xFD, from version 5),
        or a command it cannot carry out now: a negative acknowledgement (PGN 0xE800). Commands
        before a pool are NACKed once per working set and second (the rest recorded and
        counted in ``counts["nacks not sent"]``): a flood of them is not answered frame for
        frame to everyone."""
        self._record(ws, t, function, NO_OBJECT, 0xFF, why)
        if unsupported and self.options.version >= 5:
            self._send(ws.address, pad([Function.UNSUPPORTED_FUNCTION, function]))
            return
        if not unsupported and not self._early_commands.offer(ws.address, t):
            self.counts["nacks not sent"] += 1
            return
        pgn = ECU_TO_VT_PGN
        self.port.send(ACKNOWLEDGEMENT_PGN, bytes([0x01, 0xFF, 0xFF, 0xFF, ws.address,
                                                   pgn & 0xFF, (pgn >> 8) & 0xFF, pgn >> 16]),
                       GLOBAL_ADDRESS, PRIORITY)

    # -- the connection procedure ---------------------------------------------------------------

    def _used(self, ws: WorkingSet) -> int:
        """Pool bytes a working set holds (its pool and the transfers since)."""
        return (ws.pool.size if ws.pool is not None else 0) + sum(len(x) for x in ws.transfers)

    def _free_for(self, ws: WorkingSet) -> int:
        """The VT memory the other working sets leave ``ws``."""
        return self.options.memory_bytes - sum(self._used(o) for o in self.sessions.values()
                                               if o is not ws)

    def _get_memory(self, ws: WorkingSet, d: bytes, t: float) -> None:
        needed = get32(d, 2)
        ws.memory_asked_s = t
        room = self._free_for(ws)
        enough = needed <= room
        self._event(t, ws.address, "memory", f"{needed} bytes: "
                    f"{'enough' if enough else 'not enough'} (room for {room})")
        self._send(ws.address, pad([Function.GET_MEMORY, self.options.version,
                                    0 if enough else 1]))

    def _get_soft_keys(self, ws: WorkingSet, d: bytes, t: float) -> None:
        o = self.options
        self._send(ws.address, bytes([Function.GET_NUMBER_OF_SOFT_KEYS, o.navigation_soft_keys,
                                      0xFF, 0xFF, o.soft_key_width_px, o.soft_key_height_px,
                                      o.virtual_soft_keys, o.physical_soft_keys]))

    def _get_fonts(self, ws: WorkingSet, d: bytes, t: float) -> None:
        o = self.options
        self._send(ws.address, bytes([Function.GET_TEXT_FONT_DATA, 0xFF, 0xFF, 0xFF, 0xFF,
                                      o.small_fonts, o.large_fonts, o.font_styles]))

    def _get_hardware(self, ws: WorkingSet, d: bytes, t: float) -> None:
        px = self.options.data_mask_px
        # boot time unknown (0xFF), 256 colours (2), no touch screen or pointing device
        self._send(ws.address, bytes([Function.GET_HARDWARE, 0xFF, 2, 0x00]) + u16(px)
                   + u16(px))

    def _get_supported_objects(self, ws: WorkingSet, d: bytes, t: float) -> None:
        types = [int(x) for x in ObjectType if INTRODUCED_IN[x] <= self.options.version]
        self._send(ws.address, pad(bytes([Function.GET_SUPPORTED_OBJECTS, len(types)])
                                   + bytes(types)))

    def _get_window_mask_data(self, ws: WorkingSet, d: bytes, t: float) -> None:
        self._send(ws.address, pad([Function.GET_WINDOW_MASK_DATA, 1, 1]))

    def _get_versions(self, ws: WorkingSet, d: bytes, t: float) -> None:
        extended = d[0] == Function.EXTENDED_GET_VERSIONS
        labels = self.store.labels(ws.key, extended)[:255]
        code = Function.EXTENDED_GET_VERSIONS if extended else Function.GET_VERSIONS_RESPONSE
        self._send(ws.address, pad(bytes([code, len(labels)]) + b"".join(labels)))

    def _label(self, d: bytes) -> bytes:
        size = EXTENDED_LABEL_LENGTH if d[0] in (Function.EXTENDED_STORE_VERSION,
                                                 Function.EXTENDED_LOAD_VERSION,
                                                 Function.EXTENDED_DELETE_VERSION) \
            else LABEL_LENGTH
        return bytes(d[1:1 + size])

    def _store_version(self, ws: WorkingSet, d: bytes, t: float) -> None:
        label = self._label(d)
        error = 0
        if ws.pool is None or len(label) not in (LABEL_LENGTH, EXTENDED_LABEL_LENGTH):
            error = 0x08 if ws.pool is None else 0x02
        else:
            try:
                self.store.store(ws.key, label, ws.pool.raw, self.options.store_limits)
            except StoreFull as exc:
                error = 0x04      # insufficient memory available
                self._event(t, ws.address, "store refused", f"version {_show(label)}: {exc}")
            except StoreError as exc:
                error = 0x08      # any other error
                self._event(t, ws.address, "store refused", f"version {_show(label)}: {exc}")
        if not error and ws.pool is not None:
            if label not in ws.stored_labels:
                ws.stored_labels.append(label)
            for activation in reversed(self.activations):
                if activation.address == ws.address:
                    activation.version_label = _text(label)
                    break
            self._event(t, ws.address, "stored", f"version {_show(label)}, {ws.pool.size} "
                        f"bytes")
        self._send(ws.address, pad([d[0], 0xFF, 0xFF, 0xFF, 0xFF, error]))

    def _load_version(self, ws: WorkingSet, d: bytes, t: float) -> None:
        label = self._label(d)
        transfers = self.store.load(ws.key, label)
        error = 0
        if transfers is None:
            error = 0x02
            self._event(t, ws.address, "load refused", f"no version {_show(label)}")
        elif sum(len(x) for x in transfers) > self._free_for(ws):
            error = 0x04      # insufficient memory available
            self._event(t, ws.address, "load refused", f"version {_show(label)}: "
                        f"{sum(len(x) for x in transfers)} bytes, room for "
                        f"{self._free_for(ws)}")
        else:
            version = min(ws.version or self.options.version, self.options.version)
            try:
                pool = ObjectPool.from_transfers(transfers, version)
            except VtPoolError as err:
                error = 0x01
                self._event(t, ws.address, "load refused", f"version {_show(label)}: {err}")
            else:
                self._activate(ws, pool, t, f"loaded version {_show(label)}", label)
                ws.loaded_label = label
        self._send(ws.address, pad([d[0], 0xFF, 0xFF, 0xFF, 0xFF, error]))
        if not error:
            self._changed(ws, t, "pool loaded")

    def _delete_version(self, ws: WorkingSet, d: bytes, t: float) -> None:
        label = self._label(d)
        try:
            found = self.store.delete(ws.key, label)
            error = 0 if found else 0x02
            detail = "" if found else ": not stored"
        except StoreError as exc:
            error, detail = 0x08, f": {exc}"    # any other error
        self._event(t, ws.address, "deleted", f"version {_show(label)}{detail}")
        self._send(ws.address, pad([d[0], 0xFF, 0xFF, 0xFF, 0xFF, error]))

    def _transfer(self, ws: WorkingSet, d: bytes, t: float) -> None:
        if ws.memory_asked_s is None:
            self._event(t, ws.address, "out of order",
                        "object pool transfer before get memory")
        if ws.address in self._overflowed:
            return                 # out of memory already: refused at end of object pool
        room = self._free_for(ws)
        if self._used(ws) + len(d) - 1 > room:
            # the VT runs out of memory during the transfer: nothing more is kept, and the
            # end of object pool says so
            self._overflowed.add(ws.address)
            self._event(t, ws.address, "out of memory",
                        f"transfer {len(ws.transfers) + 1} of {len(d) - 1} bytes: room for "
                        f"{room} (transfers until the end of object pool are dropped)")
            ws.transfers.clear()
            return
        ws.transfers.append(bytes(d[1:]))
        self._event(t, ws.address, "transferred",
                    f"{len(d) - 1} bytes ({sum(len(x) for x in ws.transfers)} in all, "
                    f"transfer {len(ws.transfers)})")

    def _end_of_pool(self, ws: WorkingSet, d: bytes, t: float) -> None:
        base = ws.pool.raw if ws.pool is not None else ()
        transfers = tuple(base) + tuple(ws.transfers)
        total = sum(len(x) for x in transfers)
        room = self._free_for(ws)
        if total > room or ws.address in self._overflowed:
            ws.transfers.clear()
            self._overflowed.discard(ws.address)
            self._event(t, ws.address, "refused", f"out of memory: room for {room} bytes")
            self._send(ws.address, pad([Function.END_OF_OBJECT_POOL,
                                        int(EndOfPoolError.OUT_OF_MEMORY), 0xFF, 0xFF, 0xFF,
                                        0xFF, 0]))
            return
        if not transfers:
            err = VtPoolError("end of object pool without a pool",
                              code=PoolErrorCode.ANY_OTHER)
            self._event(t, ws.address, "refused", str(err))
            self._send(ws.address, err.response())
            return
        version = min(ws.version or self.options.version, self.options.version)
        try:
            pool = ObjectPool.from_transfers(transfers, version)
        except VtPoolError as err:
            ws.transfers.clear()
            self._event(t, ws.address, "refused", str(err))
            self._send(ws.address, err.response())
            return
        ws.transfers.clear()
        self._activate(ws, pool, t, f"{len(transfers)} transfer(s)")
        ws.loaded_label = None
        self._send(ws.address, pad([Function.END_OF_OBJECT_POOL, 0, 0xFF, 0xFF, 0xFF, 0xFF,
                                    0]))
        self._changed(ws, t, "pool active")

    def _activate(self, ws: WorkingSet, pool: ObjectPool, t: float, how: str,
                  label: bytes | None = None) -> None:
        ws.pool = pool
        ws.activated_s = t
        ws.open_input = None
        self.activations.append(PoolActivation(
            t, ws.address, ws.name, pool.size, len(pool), pool.version, len(pool.raw),
            pool.sha256, pool.counts(), _text(label) if label else None, label is not None))
        self._event(t, ws.address, "activated",
                    f"{len(pool)} objects, {pool.size} bytes, version {pool.version}, "
                    f"sha256 {pool.sha256[:16]}, {how}")

    _STATELESS: ClassVar[dict[int, Callable[[VirtualTerminalServer, WorkingSet, bytes, float],
                                            None]]] = {
        Function.GET_MEMORY: _get_memory,
        Function.GET_NUMBER_OF_SOFT_KEYS: _get_soft_keys,
        Function.GET_TEXT_FONT_DATA: _get_fonts,
        Function.GET_HARDWARE: _get_hardware,
        Function.GET_SUPPORTED_OBJECTS: _get_supported_objects,
        Function.GET_WINDOW_MASK_DATA: _get_window_mask_data,
        Function.GET_VERSIONS: _get_versions,
        Function.EXTENDED_GET_VERSIONS: _get_versions,
        Function.STORE_VERSION: _store_version,
        Function.EXTENDED_STORE_VERSION: _store_version,
        Function.LOAD_VERSION: _load_version,
        Function.EXTENDED_LOAD_VERSION: _load_version,
        Function.DELETE_VERSION: _delete_version,
        Function.EXTENDED_DELETE_VERSION: _delete_version,
        Function.OBJECT_POOL_TRANSFER: _transfer,
        Function.END_OF_OBJECT_POOL: _end_of_pool,
    }

    # -- the operator ----------------------------------------------------------------------------

    def key_event(self, object_id: int, activation: KeyActivation, now_s: float,
                  address: int | None = None) -> None:
        """Report a soft key or button activation to its working set.

        Raises
        ------
        ValueError
            No working set shows ``object_id``, or it is not a key or button.
        """
        ws = self._working_set(address)
        obj = ws.resolve(object_id)
        if obj is None or obj.type not in (T.KEY, T.BUTTON):
            raise ValueError(f"object {object_id} is not a soft key or button of the working "
                             f"set at 0x{ws.address:02X}")
        if obj.type == T.BUTTON and not is_enabled(obj):
            self._event(now_s, ws.address, "operator", f"button {object_id} is disabled: "
                        f"{activation.name.lower()} not sent")
            return
        parent = ws.soft_key_mask if obj.type == T.KEY else self._parent_shown(ws, object_id)
        function = Function.SOFT_KEY_ACTIVATION if obj.type == T.KEY else \
            Function.BUTTON_ACTIVATION
        self._send(ws.address, bytes([function, activation]) + u16(obj.object_id)
                   + u16(parent) + bytes([obj["key_code"], 0xFF]))
        self._event(now_s, ws.address, "operator",
                    f"{'soft key' if obj.type == T.KEY else 'button'} {obj.object_id} "
                    f"({ws.label(obj.object_id)!r}) {activation.name.lower()}")

    def enter_number(self, object_id: int, raw: int, now_s: float,
                     address: int | None = None) -> None:
        """The operator enters ``raw`` (the object's units before offset and scale) into an
        input number, list or boolean: the value is set and sent (select input object,
        change numeric value, input closed).

        Raises
        ------
        ValueError
            Not an input object, disabled, not shown, or the value outside its range.
        """
        ws = self._working_set(address)
        obj = self._input(ws, object_id, (T.INPUT_NUMBER, T.INPUT_LIST, T.INPUT_BOOLEAN))
        if obj.type == T.INPUT_NUMBER:
            low, high = obj["min_value"], obj["max_value"]
        elif obj.type == T.INPUT_LIST:
            low, high = 0, max(0, len(obj["items"]) - 1)
        else:
            low, high = 0, 1
        if not low <= raw <= high:
            raise ValueError(f"{raw} is outside {low} .. {high} of input object {object_id}")
        ref = obj.get("variable_reference", NO_OBJECT)
        holder = ws.obj(ref) if ref != NO_OBJECT else None
        (holder or obj).attrs["value"] = raw
        self._send(ws.address, pad(bytes([Function.VT_SELECT_INPUT_OBJECT]) + u16(object_id)
                                   + bytes([1, 1])))
        self._send(ws.address, bytes([Function.VT_CHANGE_NUMERIC_VALUE]) + u16(object_id)
                   + b"\xff" + u32(raw))
        self._send(ws.address, pad(bytes([Function.VT_SELECT_INPUT_OBJECT]) + u16(object_id)
                                   + bytes([1, 0])))
        self._event(now_s, ws.address, "operator", f"entered {raw} into {object_id}")
        self._changed(ws, now_s, f"operator entered {raw} into {object_id}")

    def enter_string(self, object_id: int, text: str, now_s: float,
                     address: int | None = None) -> None:
        """The operator types ``text`` into an input string (ISO 8859-1)."""
        ws = self._working_set(address)
        obj = self._input(ws, object_id, (T.INPUT_STRING,))
        raw = text.encode("latin-1")
        ref = obj.get("variable_reference", NO_OBJECT)
        holder = ws.obj(ref) if ref != NO_OBJECT else None
        target = holder or obj
        if len(raw) > target["length"]:
            raise ValueError(f"{text!r} is longer than input string {object_id}'s "
                             f"{target['length']} characters")
        target.attrs["value"] = raw + b" " * (target["length"] - len(raw))
        self._send(ws.address, pad(bytes([Function.VT_CHANGE_STRING_VALUE]) + u16(object_id)
                                   + bytes([len(raw)]) + raw))
        self._event(now_s, ws.address, "operator", f"typed {text!r} into {object_id}")
        self._changed(ws, now_s, f"operator typed into {object_id}")

    def escape(self, now_s: float, address: int | None = None) -> None:
        """The operator's ESC: closes the open input field (ESC message, function 0x04)."""
        ws = self._working_set(address)
        oid = ws.open_input if ws.open_input is not None else NO_OBJECT
        error = 0 if ws.open_input is not None else 0x01
        ws.open_input = None
        self._send(ws.address, pad(bytes([Function.VT_ESC]) + u16(oid) + bytes([error])))
        self._event(now_s, ws.address, "operator", "ESC")

    def _working_set(self, address: int | None) -> WorkingSet:
        ws = self.sessions.get(address) if address is not None else self.active_working_set
        if ws is None or ws.pool is None:
            who = f"at 0x{address:02X}" if address is not None else "active"
            raise ValueError(f"no working set {who} with an active pool on the VT")
        return ws

    def _input(self, ws: WorkingSet, object_id: int,
               types: tuple[ObjectType, ...]) -> VtObject:
        obj = ws.resolve(object_id)
        if obj is None or obj.type not in types or obj.type not in INPUTS:
            raise ValueError(f"object {object_id} is not an input "
                             f"{'/'.join(t.name.lower() for t in types)}")
        if not is_enabled(obj):
            raise ValueError(f"input object {object_id} is disabled")
        if not ws.is_shown(object_id):
            raise ValueError(f"input object {object_id} is not on the active mask")
        return obj

    def _parent_shown(self, ws: WorkingSet, object_id: int) -> int:
        for obj, _x, _y, parent in ws.visible():
            if obj.object_id == object_id:
                return parent
        return ws.active_mask


_COMMAND_FUNCTIONS = frozenset(range(0xA0, 0xC0))
#: functions of the VT's own messages, which a working set answers with the same function
_RESPONSES = frozenset({Function.SOFT_KEY_ACTIVATION, Function.BUTTON_ACTIVATION,
                        Function.POINTING_EVENT, Function.VT_SELECT_INPUT_OBJECT,
                        Function.VT_ESC, Function.VT_CHANGE_NUMERIC_VALUE,
                        Function.VT_CHANGE_ACTIVE_MASK, Function.VT_CHANGE_SOFT_KEY_MASK,
                        Function.VT_CHANGE_STRING_VALUE, 0x09, 0x0A})


def _text(label: bytes) -> str:
    return label.decode("latin-1").rstrip()


def _show(label: bytes) -> str:
    return repr(_text(label))


VT_FUNCTION = 29
"""ISO 11783-1 function code of a virtual terminal."""
VT_ADDRESS = 0x26
"""The VT's preferred address (38: the first VT of ISO 11783-5's preferred addresses)."""
VT_NAME = IsobusName(identity_number=0x1E7, manufacturer_code=0, function=VT_FUNCTION,
                     device_class=0, industry_group=2)
"""The rig's VT NAME (identity number arbitrary, manufacturer code 0)."""


def add_vt(network: IsobusNetwork, options: VtOptions | None = None,
           store: VersionStore | None = None, name: IsobusName = VT_NAME,
           address: int = VT_ADDRESS) -> VirtualTerminalServer:
    """Host the VT on ``network`` (the tractor's, beside its TC) and run it.

    This is all the tractor and ``hil isobus serve`` need::

        vt = add_vt(tractor.network, VtOptions(version=4), VersionStore(out / "vt-store"))
    """
    cf = network.add(name, address, "VT")
    vt = VirtualTerminalServer(cf, options, store)
    cf.run(vt)
    return vt
