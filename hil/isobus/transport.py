"""TP and ETP sessions, as sender and as receiver (ISO 11783-3, clauses 5.10-5.11).

One :class:`TransportLayer` serves every internal control function of a network. It keeps one
session per (source, destination) pair and direction, so several transfers run at once (to
different peers, both ways, a BAM beside a peer-to-peer transfer); a second message for a pair
that is busy waits for the first to end. Nothing here reads a clock: the owner calls
:meth:`TransportLayer.poll` with the run time and asks :meth:`TransportLayer.next_due` when to
call again, and every frame goes out through the ``send_frame`` callback at that time.

Timeouts (ISO 11783-3, clause 5.12.3; the same as SAE J1939-21):

- Tr = 200 ms: the most a node may take to respond (this layer answers at once).
- Th = 500 ms: a receiver that holds the connection (CTS for 0 packets) repeats the hold
  within Th.
- T1 = 750 ms: a receiver waiting for the next data packet.
- T2 = 1,250 ms: a receiver waiting for the first data packet after its CTS.
- T3 = 1,250 ms: a sender waiting for a CTS or the end-of-message acknowledgement after its
  last data packet.
- T4 = 1,050 ms: a sender held by a CTS for 0 packets, waiting for the next CTS.
- A BAM's data packets go 50 ms apart (SAE J1939-21: 50 to 200 ms; whether ISO 11783-3 allows
  a shorter gap could not be checked against its text here). The receiver of a BAM times out
  after T1. :attr:`TransportTiming.bam_interval_s` changes the gap.

A receiver that times out sends an abort with reason 3 (a BAM receiver drops the message
silently, BAM has no aborts); a sender that times out does the same.

What a peer may take of the receiver (a hostile or broken peer must not starve a good one):

- a transfer (RTS, ETP RTS or BAM) from an address that never claimed (ISO 11783-5: no
  control function sends before its claim) is not answered: it is counted
  (:attr:`TransportLayer.counts` ``unclaimed``), not logged a line per frame;
- at most :attr:`TransportTiming.max_sessions_per_source` peer-to-peer receive sessions per
  source and :attr:`TransportTiming.max_sessions` in all: one more RTS is aborted with reason 1
  (already in one or more connection-managed sessions);
- a message larger than :attr:`TransportTiming.max_receive_bytes` is aborted with reason 2
  (system resources needed elsewhere) at its RTS, before any byte is kept;
- the ends of transfers are kept as the last :data:`EVENTS_KEPT` events, and counted.
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from hil.errors import FrameError
from hil.isobus.port import GLOBAL_ADDRESS, Received
from hil.isobus.tp_messages import (
    BYTES_PER_PACKET,
    ETP_MAX_BYTES,
    PGN_ETP_CM,
    PGN_ETP_DT,
    PGN_TP_CM,
    PGN_TP_DT,
    TP_MAX_BYTES,
    AbortReason,
    CmFrame,
    Control,
    data_packet,
    decode_cm,
    encode_cm,
    packets_for,
)

INF = float("inf")
TP_PRIORITY = 7
"""Priority of TP and ETP frames (ISO 11783-3 and J1939-21 use the lowest)."""
EVENTS_KEPT = 1000
"""How many of the last transfer ends :attr:`TransportLayer.events` keeps (all are counted)."""


@dataclass(frozen=True)
class TransportTiming:
    """The standard's timeouts and this layer's choices, in seconds and packets.

    Parameters
    ----------
    t1_s, t2_s, t3_s, t4_s, tr_s, th_s : float
        ISO 11783-3's timeouts (see the module docstring).
    bam_interval_s : float
        Time between a BAM's packets (and from the BAM to its first packet).
    tp_cts_packets : int
        Most packets this layer asks for in one TP CTS (the sender's RTS limit also applies).
    etp_cts_packets : int
        Most packets this layer asks for in one ETP CTS (at most 255).
    max_sessions : int
        Most receive sessions (TP and ETP, not BAM) at once; one more RTS is aborted with
        reason 1.
    max_sessions_per_source : int
        Most of those from one source address (to different local functions); one more RTS
        from it is aborted with reason 1.
    max_receive_bytes : int
        Largest message this layer receives; an RTS announcing more is aborted with reason 2.
    max_retransmits : int
        CTS frames asking again for packets already sent that a sender accepts before it
        aborts with reason 5.
    """

    t1_s: float = 0.75
    t2_s: float = 1.25
    t3_s: float = 1.25
    t4_s: float = 1.05
    tr_s: float = 0.2
    th_s: float = 0.5
    bam_interval_s: float = 0.05
    tp_cts_packets: int = 16
    etp_cts_packets: int = 255
    max_sessions: int = 16
    max_retransmits: int = 2
    max_sessions_per_source: int = 2
    max_receive_bytes: int = 1 << 21


@dataclass(frozen=True)
class TransportEvent:
    """How a transfer ended, as this layer saw it.

    Attributes
    ----------
    time_s : float
        Run time of the end.
    kind : str
        ``complete``; ``aborted`` (this layer sent the abort); ``peer-aborted`` (the other
        side did); ``timeout`` (this layer timed out and aborted); ``dropped`` (a BAM left
        incomplete, or a session replaced by a new RTS); ``refused`` (an RTS this layer
        aborted at once).
    role : str
        ``sender`` or ``receiver``.
    protocol : str
        ``BAM``, ``TP`` or ``ETP``.
    pgn, source, destination, size : int
        The message's PGN, its sender and receiver, its size in bytes.
    reason : int or None
        The abort reason, if aborted.
    detail : str
        What happened, for logs.
    """

    time_s: float
    kind: str
    role: str
    protocol: str
    pgn: int
    source: int
    destination: int
    size: int
    reason: int | None = None
    detail: str = ""


class TransportHooks(Protocol):
    """Where fault injection reaches into the sessions (see :mod:`hil.isobus.faults`)."""

    def drop_cts(self, session: Session) -> bool:
        """Whether to leave out the CTS this receiving session is about to send."""

    def abort_reason(self, session: Session, packets_done: int) -> int | None:
        """An abort reason to end ``session`` with after ``packets_done`` data packets."""

    def packet_delay_s(self, session: Session, packet_number: int) -> float:
        """Extra delay before this sending session sends ``packet_number``."""


class NoFaults:
    """Hooks that change nothing."""

    def drop_cts(self, session: Session) -> bool:
        """Never drop a CTS."""
        return False

    def abort_reason(self, session: Session, packets_done: int) -> int | None:
        """Never abort."""
        return None

    def packet_delay_s(self, session: Session, packet_number: int) -> float:
        """Never delay."""
        return 0.0


@dataclass
class Session:
    """One transfer in progress (sender or receiver side).

    Attributes
    ----------
    role : str
        ``sender`` or ``receiver``.
    protocol : str
        ``BAM``, ``TP`` or ``ETP``.
    pgn, source, destination, size, priority : int
        The message being carried.
    data : bytearray
        The payload (sender: all of it; receiver: the packets that have arrived).
    """

    role: str
    protocol: str
    pgn: int
    source: int
    destination: int
    size: int
    priority: int
    data: bytearray
    total: int = 0
    #: receiver: next packet number expected; sender: highest packet number sent + 1
    next_packet: int = 1
    #: receiver: last packet number of the current CTS window
    window_end: int = 0
    #: receiver: packets the current CTS allowed; ETP: the DPO's offset, None before the DPO
    window_packets: int = 0
    dpo_offset: int | None = None
    #: sender: data packets waiting to go (due time, packet number)
    pending: deque[tuple[float, int]] = field(default_factory=deque)
    #: sender (ETP): offset of the window being sent
    offset: int = 0
    deadline: float = INF
    waiting_for: str = ""
    packets_done: int = 0
    retransmits: int = 0
    ctses: int = 0

    def __post_init__(self) -> None:
        self.total = packets_for(self.size)

    @property
    def key(self) -> tuple[int, int]:
        """(source, destination) of the message."""
        return (self.source, self.destination)


SendFrame = Callable[[int, int, int, int, bytes], None]
"""``send_frame(priority, pgn, source, destination, data)``: put one frame on the bus now."""


class TransportLayer:
    """TP (BAM, RTS/CTS) and ETP sessions of one network, as sender and receiver.

    Parameters
    ----------
    send_frame : SendFrame
        Puts one frame on the bus at the current run time.
    deliver : callable
        Gets every message received whole, as a :class:`~hil.isobus.port.Received`.
    timing : TransportTiming
        Timeouts and window sizes.
    hooks : TransportHooks, optional
        Fault injection; none by default.
    claimed : callable, optional
        ``claimed(address)``: whether a control function claimed ``address``; transfers from
        one that did not are not answered. ``None``: every address is taken as claimed.
    """

    def __init__(self, send_frame: SendFrame, deliver: Callable[[Received], None],
                 timing: TransportTiming | None = None,
                 hooks: TransportHooks | None = None,
                 claimed: Callable[[int], bool] | None = None) -> None:
        self._send_frame = send_frame
        self._deliver = deliver
        self.timing = timing or TransportTiming()
        self.hooks: TransportHooks = hooks or NoFaults()
        self._out: dict[tuple[int, int], Session] = {}
        self._queued: dict[tuple[int, int], deque[Session]] = {}
        self._in: dict[tuple[int, int], Session] = {}
        self._claimed = claimed
        #: the last EVENTS_KEPT transfer ends
        self.events: deque[TransportEvent] = deque(maxlen=EVENTS_KEPT)
        #: every transfer end by kind, and ``unclaimed``: transfers from unclaimed addresses
        self.counts: Counter[str] = Counter()
        self._now = 0.0

    # -- public ----------------------------------------------------------------------------

    def send(self, pgn: int, data: bytes, source: int, destination: int, priority: int,
             now: float) -> None:
        """Start (or queue behind a busy pair) a transfer of more than 8 bytes.

        Raises
        ------
        FrameError
            8 bytes or fewer (a single frame), a broadcast beyond 1,785 bytes (ETP has no
            broadcast), or more than 117,440,505 bytes.
        """
        size = len(data)
        if size <= 8:
            raise FrameError(f"PGN 0x{pgn:05X}: {size} bytes go in a single frame, not TP")
        if size > ETP_MAX_BYTES:
            raise FrameError(f"PGN 0x{pgn:05X}: {size} bytes exceed ETP's {ETP_MAX_BYTES}")
        if destination == GLOBAL_ADDRESS:
            if size > TP_MAX_BYTES:
                raise FrameError(f"PGN 0x{pgn:05X}: {size} bytes to everyone: a broadcast (BAM) "
                                 f"carries at most {TP_MAX_BYTES} bytes and ETP is "
                                 f"destination-specific only")
            protocol = "BAM"
        else:
            protocol = "TP" if size <= TP_MAX_BYTES else "ETP"
        session = Session("sender", protocol, pgn, source, destination, size, priority,
                          bytearray(data))
        self._now = now
        if session.key in self._out:
            self._queued.setdefault(session.key, deque()).append(session)
            return
        self._start(session, now)

    def busy(self) -> bool:
        """Whether any session is open or queued."""
        return bool(self._out or self._in or any(self._queued.values()))

    def sessions(self) -> list[Session]:
        """The open sessions (senders first)."""
        return [*self._out.values(), *self._in.values()]

    def next_due(self) -> float:
        """The earliest run time at which :meth:`poll` has something to do (``inf``: none)."""
        due = INF
        for s in self._out.values():
            if s.pending:
                due = min(due, s.pending[0][0])
            due = min(due, s.deadline)
        for s in self._in.values():
            due = min(due, s.deadline)
        return due

    def poll(self, now: float) -> None:
        """Send the data packets that are due and time out the sessions that are late."""
        self._now = now
        for session in list(self._out.values()):
            self._send_due_packets(session, now)
            if self._out.get(session.key) is session and session.deadline <= now:
                self._abort(session, AbortReason.TIMEOUT, now, kind="timeout",
                            detail=f"sender waited for {session.waiting_for}")
        for session in list(self._in.values()):
            if session.deadline <= now:
                if session.protocol == "BAM":
                    self._end(session, now, "dropped", detail="no data packet within T1")
                else:
                    self._abort(session, AbortReason.TIMEOUT, now, kind="timeout",
                                detail=f"receiver waited for {session.waiting_for}")

    def on_frame(self, pgn: int, source: int, destination: int, data: bytes,
                 priority: int, now: float) -> None:
        """Take a TP/ETP frame addressed to a local control function (or a BAM's).

        Frames of other PGNs are ignored. A malformed connection-management frame is recorded
        as a ``refused`` event with the decoder's message.
        """
        self._now = now
        if pgn in (PGN_TP_CM, PGN_ETP_CM):
            try:
                cm = decode_cm(data, extended=pgn == PGN_ETP_CM)
            except FrameError as exc:
                self._record(TransportEvent(now, "refused", "receiver",
                                            "ETP" if pgn == PGN_ETP_CM else "TP", 0,
                                            source, destination, 0, detail=str(exc)))
                return
            self._on_cm(cm, source, destination, priority, now)
        elif pgn in (PGN_TP_DT, PGN_ETP_DT):
            session = self._in.get((source, destination))
            if session is None or (session.protocol == "ETP") != (pgn == PGN_ETP_DT):
                return   # not a transfer of ours: J1939-21 says ignore it
            if len(data) < 1:
                return
            self._on_data(session, data[0], bytes(data[1:8]), now)

    # -- sender ----------------------------------------------------------------------------

    def _start(self, s: Session, now: float) -> None:
        self._out[s.key] = s
        if s.protocol == "BAM":
            self._cm(s, CmFrame(Control.BAM, s.pgn, size=s.size, packets=s.total))
            due = now
            for n in range(1, s.total + 1):
                due += self.timing.bam_interval_s + self.hooks.packet_delay_s(s, n)
                s.pending.append((due, n))
            return
        if s.protocol == "TP":
            self._cm(s, CmFrame(Control.RTS, s.pgn, size=s.size, packets=s.total,
                                max_per_cts=0xFF))
        else:
            self._cm(s, CmFrame(Control.ETP_RTS, s.pgn, size=s.size))
        self._wait(s, now + self.timing.t3_s, "a CTS after the RTS (T3)")

    def _send_due_packets(self, s: Session, now: float) -> None:
        while s.pending and s.pending[0][0] <= now:
            _, number = s.pending.popleft()
            seq = number - s.offset
            chunk = bytes(s.data[(number - 1) * BYTES_PER_PACKET:number * BYTES_PER_PACKET])
            dt_pgn = PGN_ETP_DT if s.protocol == "ETP" else PGN_TP_DT
            self._send_frame(TP_PRIORITY, dt_pgn, s.source, s.destination,
                             data_packet(seq, chunk))
            s.packets_done += 1
            s.next_packet = max(s.next_packet, number + 1)
            reason = self.hooks.abort_reason(s, s.packets_done)
            if reason is not None:
                self._abort(s, reason, now, kind="aborted",
                            detail=f"fault injected after {s.packets_done} packets")
                return
        if s.pending:
            return
        if s.protocol == "BAM" and s.next_packet > s.total:
            self._end(s, now, "complete")
        elif s.protocol != "BAM" and s.waiting_for == "sending":
            what = ("the end-of-message acknowledgement (T3)" if s.next_packet > s.total
                    else "the next CTS (T3)")
            self._wait(s, now + self.timing.t3_s, what)

    def _on_cts(self, s: Session, cm: CmFrame, now: float) -> None:
        etp = s.protocol == "ETP"
        if etp and cm.pgn != s.pgn:
            self._abort(s, AbortReason.CTS_PGN, now,
                        detail=f"ETP CTS for PGN 0x{cm.pgn:05X}, connection carries "
                               f"0x{s.pgn:05X}")
            return
        if s.pending:
            self._abort(s, AbortReason.CTS_DURING_TRANSFER, now,
                        detail="CTS while data packets of the last CTS were still going out")
            return
        if cm.packets == 0:
            self._wait(s, now + self.timing.t4_s, "a CTS after a hold (T4)")
            return
        last = cm.next_packet + cm.packets - 1
        if cm.next_packet < 1 or last > s.total:
            self._abort(s, AbortReason.CTS_EXCEEDS_SIZE if etp else AbortReason.OTHER, now,
                        detail=f"CTS asks for packets {cm.next_packet}..{last} of {s.total}")
            return
        if cm.next_packet < s.next_packet:
            s.retransmits += 1
            if s.retransmits > self.timing.max_retransmits:
                self._abort(s, AbortReason.MAX_RETRANSMIT, now,
                            detail=f"retransmission asked {s.retransmits} times")
                return
        if etp:
            s.offset = cm.next_packet - 1
            self._cm(s, CmFrame(Control.ETP_DPO, s.pgn, packets=cm.packets, offset=s.offset))
        due = now
        for n in range(cm.next_packet, last + 1):
            due += self.hooks.packet_delay_s(s, n)
            s.pending.append((due, n))
        s.waiting_for, s.deadline = "sending", INF
        self._send_due_packets(s, now)

    # -- receiver --------------------------------------------------------------------------

    def _on_cm(self, cm: CmFrame, source: int, destination: int, priority: int,
               now: float) -> None:
        c = cm.control
        if c in (Control.RTS, Control.ETP_RTS, Control.BAM):
            self._on_rts(cm, source, destination, priority, now)
        elif c in (Control.CTS, Control.ETP_CTS):
            s = self._out.get((destination, source))
            if s is not None and s.protocol != "BAM" and (s.protocol == "ETP") == (
                    c == Control.ETP_CTS) and (c == Control.ETP_CTS or cm.pgn == s.pgn):
                self._on_cts(s, cm, now)
        elif c in (Control.EOMA, Control.ETP_EOMA):
            s = self._out.get((destination, source))
            if s is not None and s.pgn == cm.pgn and s.protocol != "BAM":
                self._end(s, now, "complete")
        elif c == Control.ETP_DPO:
            r = self._in.get((source, destination))
            if r is not None and r.protocol == "ETP":
                self._on_dpo(r, cm, now)
        elif c == Control.ABORT:
            mine = self._out.get((destination, source))
            if mine is not None and mine.pgn == cm.pgn and mine.protocol != "BAM":
                self._end(mine, now, "peer-aborted", reason=cm.reason)
            theirs = self._in.get((source, destination))
            if theirs is not None and theirs.pgn == cm.pgn and theirs.protocol != "BAM":
                self._end(theirs, now, "peer-aborted", reason=cm.reason)

    def _on_rts(self, cm: CmFrame, source: int, destination: int, priority: int,
                now: float) -> None:
        protocol = {Control.RTS: "TP", Control.ETP_RTS: "ETP", Control.BAM: "BAM"}[cm.control]
        if (protocol == "BAM") != (destination == GLOBAL_ADDRESS):
            return   # a BAM to one address or an RTS to everyone: not a valid connection
        if self._claimed is not None and not self._claimed(source):
            # no claim, no connection (ISO 11783-5): not answered, counted, not logged per frame
            self.counts["unclaimed"] += 1
            return
        size = cm.size
        # the buffer grows as packets arrive (in order, or the session is aborted): an RTS
        # announcing 117 MB costs nothing until the data comes
        s = Session("receiver", protocol, cm.pgn, source, destination, size, priority,
                    bytearray())
        if protocol == "ETP":
            bad = not TP_MAX_BYTES < size <= ETP_MAX_BYTES
        else:
            bad = not 9 <= size <= TP_MAX_BYTES or cm.packets != s.total
        old = self._in.pop(s.key, None)
        if old is not None:
            self._record(self._event(old, now, "dropped", detail="replaced by a new connection"))
        if bad:
            detail = f"{protocol} announces {size} bytes in {cm.packets} packets"
            self._refuse(s, AbortReason.OTHER, now, detail)
            return
        if size > self.timing.max_receive_bytes:
            self._refuse(s, AbortReason.RESOURCES_NEEDED, now,
                         f"{protocol} announces {size} bytes; this receiver takes at most "
                         f"{self.timing.max_receive_bytes}")
            return
        if protocol != "BAM":
            peer = [r for r in self._in.values() if r.protocol != "BAM"]
            from_source = sum(1 for r in peer if r.source == source)
            if len(peer) >= self.timing.max_sessions:
                self._refuse(s, AbortReason.ALREADY_IN_SESSION, now,
                             f"{len(peer)} sessions already open")
                return
            if from_source >= self.timing.max_sessions_per_source:
                self._refuse(s, AbortReason.ALREADY_IN_SESSION, now,
                             f"{from_source} sessions from 0x{source:02X} already open")
                return
        self._in[s.key] = s
        if protocol == "BAM":
            self._wait(s, now + self.timing.t1_s, "the first BAM packet (T1)")
            return
        limit = cm.max_per_cts if protocol == "TP" and cm.max_per_cts != 0xFF else 255
        s.window_packets = min(limit, self.timing.tp_cts_packets if protocol == "TP"
                               else self.timing.etp_cts_packets)
        self._send_cts(s, now)

    def _refuse(self, s: Session, reason: AbortReason, now: float, detail: str) -> None:
        """Abort an RTS at once (a BAM has no abort: it is dropped)."""
        if s.protocol != "BAM":
            self._cm_from_receiver(s, CmFrame(Control.ABORT, s.pgn, reason=reason))
        self._record(self._event(s, now, "refused",
                                 reason=int(reason) if s.protocol != "BAM" else None,
                                 detail=detail))

    def _send_cts(self, s: Session, now: float) -> None:
        n = min(s.window_packets, s.total - s.next_packet + 1)
        s.window_end = s.next_packet + n - 1
        s.dpo_offset = None
        s.ctses += 1
        if self.hooks.drop_cts(s):
            # the CTS is left out: the sender must time out (T3) and abort; this side waits
            # T2 + T3 so that the sender's abort, not its own, is what the bus shows
            self._wait(s, now + self.timing.t2_s + self.timing.t3_s,
                       "data after a dropped CTS")
            return
        if s.protocol == "TP":
            cm = CmFrame(Control.CTS, s.pgn, packets=n, next_packet=s.next_packet)
        else:
            cm = CmFrame(Control.ETP_CTS, s.pgn, packets=n, next_packet=s.next_packet)
        self._cm_from_receiver(s, cm)
        self._wait(s, now + self.timing.t2_s, "the first data packet after the CTS (T2)")

    def _on_dpo(self, s: Session, cm: CmFrame, now: float) -> None:
        if cm.pgn != s.pgn:
            self._abort(s, AbortReason.DPO_PGN, now,
                        detail=f"DPO for PGN 0x{cm.pgn:05X}, connection carries 0x{s.pgn:05X}")
        elif s.dpo_offset is not None:
            self._abort(s, AbortReason.UNEXPECTED_DPO, now, detail="second DPO in one window")
        elif cm.packets > s.window_end - s.next_packet + 1:
            self._abort(s, AbortReason.DPO_PACKETS_EXCEED_CTS, now,
                        detail=f"DPO for {cm.packets} packets, the CTS allowed "
                               f"{s.window_end - s.next_packet + 1}")
        elif cm.offset != s.next_packet - 1:
            self._abort(s, AbortReason.BAD_DPO_OFFSET, now,
                        detail=f"DPO offset {cm.offset}, expected {s.next_packet - 1}")
        else:
            s.dpo_offset = cm.offset
            s.window_end = cm.offset + cm.packets
            self._wait(s, now + self.timing.t1_s, "the data packets after the DPO (T1)")

    def _on_data(self, s: Session, seq: int, chunk: bytes, now: float) -> None:
        if s.protocol == "BAM":
            if seq != s.next_packet:
                self._end(s, now, "dropped", detail=f"BAM packet {seq}, expected {s.next_packet}")
                return
        elif s.protocol == "ETP" and s.dpo_offset is None:
            self._abort(s, AbortReason.UNEXPECTED_DATA, now, detail="ETP data before a DPO")
            return
        elif s.next_packet > s.window_end:
            self._abort(s, AbortReason.UNEXPECTED_DATA, now,
                        detail=f"data packet {seq} outside the CTS window")
            return
        number = seq + (s.dpo_offset or 0) if s.protocol == "ETP" else seq
        if s.protocol != "BAM":
            if number < s.next_packet:
                self._abort(s, AbortReason.DUPLICATE_SEQUENCE, now,
                            detail=f"packet {number} again (expected {s.next_packet})")
                return
            if number > s.next_packet:
                self._abort(s, AbortReason.BAD_SEQUENCE, now,
                            detail=f"packet {number}, expected {s.next_packet}")
                return
        s.data += chunk.ljust(BYTES_PER_PACKET, b"\xff")
        s.next_packet += 1
        s.packets_done += 1
        reason = self.hooks.abort_reason(s, s.packets_done)
        if reason is not None and s.protocol != "BAM":
            self._abort(s, reason, now, kind="aborted",
                        detail=f"fault injected after {s.packets_done} packets")
            return
        if s.next_packet > s.total:
            if s.protocol == "TP":
                self._cm_from_receiver(s, CmFrame(Control.EOMA, s.pgn, size=s.size,
                                                  packets=s.total))
            elif s.protocol == "ETP":
                self._cm_from_receiver(s, CmFrame(Control.ETP_EOMA, s.pgn, size=s.size))
            self._end(s, now, "complete")
            self._deliver(Received(s.pgn, bytes(s.data[:s.size]), s.source, s.destination,
                                   now, s.priority))
            return
        if s.protocol != "BAM" and s.next_packet > s.window_end:
            self._send_cts(s, now)
        else:
            self._wait(s, now + self.timing.t1_s, "the next data packet (T1)")

    # -- common ----------------------------------------------------------------------------

    def _wait(self, s: Session, deadline: float, what: str) -> None:
        s.deadline, s.waiting_for = deadline, what

    def _cm(self, s: Session, cm: CmFrame) -> None:
        pgn = PGN_ETP_CM if s.protocol == "ETP" else PGN_TP_CM
        self._send_frame(TP_PRIORITY, pgn, s.source, s.destination, encode_cm(cm))

    def _cm_from_receiver(self, s: Session, cm: CmFrame) -> None:
        pgn = PGN_ETP_CM if s.protocol == "ETP" else PGN_TP_CM
        self._send_frame(TP_PRIORITY, pgn, s.destination, s.source, encode_cm(cm))

    def _abort(self, s: Session, reason: int, now: float, kind: str = "aborted",
               detail: str = "") -> None:
        cm = CmFrame(Control.ABORT, s.pgn, reason=int(reason))
        if s.protocol != "BAM":
            if s.role == "sender":
                self._cm(s, cm)
            else:
                self._cm_from_receiver(s, cm)
        self._end(s, now, kind, reason=int(reason), detail=detail)

    def _record(self, event: TransportEvent) -> None:
        self.events.append(event)
        self.counts[event.kind] += 1

    def _event(self, s: Session, now: float, kind: str, reason: int | None = None,
               detail: str = "") -> TransportEvent:
        return TransportEvent(now, kind, s.role, s.protocol, s.pgn, s.source, s.destination,
                              s.size, reason, detail)

    def _end(self, s: Session, now: float, kind: str, reason: int | None = None,
             detail: str = "") -> None:
        table = self._out if s.role == "sender" else self._in
        if table.get(s.key) is s:
            del table[s.key]
        s.pending.clear()
        self._record(self._event(s, now, kind, reason, detail))
        if s.role == "sender":
            queue = self._queued.get(s.key)
            if queue:
                self._start(queue.popleft(), now)
                if not queue:
                    del self._queued[s.key]
