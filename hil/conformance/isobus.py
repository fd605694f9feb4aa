"""ISOBUS bus conformance of a DUT, judged from a run's bus log (ISO 11783-3, -5, -6, -10).

Pure functions over the frames of one run: a :class:`~hil.conformance.framelog.FrameLog`
(``rx`` True: the DUT's frames, as :mod:`hil.conformance.measure` reads them) or a list of
``(time_s, can.Message, rx)``. Each returns a :class:`~hil.measurements.Measurement` with its
limit (the constants below, each derived where it is defined) and a detail dictionary.

- :func:`claim_frames_before` (``isobus.claim.frames_before``): frames the DUT sent from an
  address before its claim of it, or within the 250 ms after the claim (ISO 11783-5, 4.4.2).
- :func:`claim_requests_unanswered` (``isobus.claim.request_answered``): requests for the
  address-claimed PGN (PGN 0xEA00 for 0xEE00) that the DUT did not answer with its claim within
  Tr = 200 ms.
- :func:`claim_contention` (``isobus.claim.contention``): frames the DUT sent from an address
  after a lower NAME claimed it (a contender injected by :mod:`hil.isobus.faults`).
- :func:`transport_violations` (``isobus.transport.violations``): TP/ETP protocol errors of
  the DUT as sender or receiver, counted by kind.
- :func:`pgn_rates` (``isobus.pgn.rate``): the median period of each cyclic PGN the DUT sends
  against the period its standard declares (:data:`ISOBUS_CYCLIC`).

Which frames are the DUT's: those with ``rx`` set (the rig received them), as for the CANopen
checks; the rig's own frames (its claims, requests, the contender it injects, its side of a
transfer) have ``rx`` False. Only 29-bit frames are read, decoded once and walked in Python:
measured 8.4 us per frame for all five measurements (a 600 s log of our TC client and TC with
a 100 Hz message beside them, 61,393 frames, in 0.5 s), small beside the run; the CANopen
checks' vectorised path is for the 120,000-frame depth runs.

``resolution_s`` is how finely the log places a DUT frame in time (the rig's physics step in
real time, the control period in lockstep, as :mod:`hil.conformance.measure` uses): every time
comparison gives the DUT that much benefit of the doubt.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np

from hil.conformance.checks import cycle_stats
from hil.conformance.framelog import FrameLog
from hil.errors import FrameError
from hil.isobus.can_id import decode_id
from hil.isobus.port import GLOBAL_ADDRESS, NULL_ADDRESS
from hil.isobus.tp_messages import (
    PGN_ADDRESS_CLAIMED,
    PGN_ETP_CM,
    PGN_ETP_DT,
    PGN_REQUEST,
    PGN_TP_CM,
    PGN_TP_DT,
    TP_MAX_BYTES,
    Control,
    decode_cm,
    packets_for,
)
from hil.measurements import Measurement

# -- limits and the standard's times ----------------------------------------------------------

#: ISO 11783-5, 4.4.2: a control function sends nothing but its claim (and requests for the
#: address-claimed PGN from the null address) before it has claimed an address and for 250 ms
#: after. A single frame too early is already a breach, so the limit is 0.
FRAMES_BEFORE_CLAIM_LIMIT = 0
#: ISO 11783-5 requires every control function to answer a request for the address-claimed
#: PGN (to everyone or to it); a request left unanswered is a breach: limit 0.
UNANSWERED_REQUESTS_LIMIT = 0
#: ISO 11783-5, 4.4.3: the control function that loses a contention stops using the address at
#: once (it claims another or sends cannot-claim from 0xFE); one frame more is a breach: limit 0.
CONTENTION_FRAMES_LIMIT = 0
#: ISO 11783-3: every TP/ETP rule below is a "shall"; a single breach is a failure: limit 0.
TRANSPORT_VIOLATIONS_LIMIT = 0
#: The median period of a cyclic PGN may be off its declared period by +/- this many %:
#: the same band as the CANopen cycle check (``bus.cycle_time.median``) so that both buses are
#: judged alike; ISO 11783-6/-10 give the periods but no tolerance of their own.
PGN_RATE_TOLERANCE_PCT = 10.0

CLAIM_WAIT_S = 0.25
"""ISO 11783-5: the silence after an address claim before other traffic."""
TR_S = 0.2
"""ISO 11783-3 Tr (as SAE J1939-21): the most a node may take to respond, also to a request."""
T1_S, T2_S, T3_S, T4_S = 0.75, 1.25, 1.25, 1.05
"""ISO 11783-3 timeouts (clause 5.12.3; as SAE J1939-21): T1 receiver waiting for the next data
packet, T2 receiver waiting for data after its CTS, T3 sender waiting for a CTS or the
EndOfMsgAck, T4 sender held by a CTS for 0 packets."""
BAM_MIN_INTERVAL_S = 0.010
"""Least time between a BAM's packets (and from the BAM to its first packet). Sources differ:
SAE J1939-21 requires 50 to 200 ms; ISO 11783-3:2018, 5.13.3 allows 10 to 200 ms (as quoted by
an open ISOBUS stack's source, the standard's text was not read here). An ISOBUS DUT is held to
ISO 11783-3; pass ``bam_min_s=0.05`` to :func:`transport_violations` for a J1939 one."""
BAM_MAX_INTERVAL_S = 0.200
"""Most time between a BAM's packets (both sources agree); a longer gap is reported as
``bam-too-slow``."""

PROCESS_DATA_PGN = 0xCB00
ECU_TO_VT_PGN = 0xE700


@dataclass(frozen=True)
class CyclicPgn:
    """A parameter group an ISOBUS DUT sends periodically.

    Attributes
    ----------
    label : str
        What it is, for the measurement's conditions.
    pgn : int
        Its PGN (PDU1 groups with the destination byte 0).
    first_byte : int or None
        The first data byte that tells it from other messages of the same PGN (a process data
        command, a VT function), ``None``: every frame of the PGN.
    period_ms : float
        The declared period.
    source : str
        Where the period is declared.
    """

    label: str
    pgn: int
    first_byte: int | None
    period_ms: float
    source: str


#: The cyclic messages an implement's working set sends by the standards. Not cyclic, so not
#: here: the working-set master message (PGN 0xFE0D, ISO 11783-7), sent once after the claim
#: and on request; the TECU's 100 ms messages are the tractor's, not an implement's.
ISOBUS_CYCLIC: tuple[CyclicPgn, ...] = (
    CyclicPgn("TC client task", PROCESS_DATA_PGN, 0xFF, 2000.0,
              "ISO 11783-10: the client task message (process data command 0xF) every 2 s "
              "while connected to a TC"),
    CyclicPgn("VT working set maintenance", ECU_TO_VT_PGN, 0xFF, 1000.0,
              "ISO 11783-6: the working set maintenance message (VT function 0xFF) every 1 s "
              "while connected to a VT"),
)


# -- frames -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class IsobusFrame:
    """A 29-bit frame of the log, decoded: when, PGN, addresses, data, whether the DUT's."""

    time_s: float
    pgn: int
    source: int
    destination: int
    data: bytes
    rx: bool


Frames = FrameLog | Sequence[tuple[float, can.Message, bool]] | Sequence[IsobusFrame]


def isobus_frames(frames: Frames) -> list[IsobusFrame]:
    """The 29-bit frames of ``frames`` in time order (stable), decoded to PGN and addresses
    (a list of :class:`IsobusFrame` is returned as it is: decode once, judge many times)."""
    out: list[IsobusFrame] = []
    if isinstance(frames, list) and all(isinstance(f, IsobusFrame) for f in frames):
        return frames  # type: ignore[return-value]
    if isinstance(frames, FrameLog):
        ext = np.flatnonzero(frames.extended)
        rows = zip(frames.time_s[ext].tolist(), frames.can_id[ext].tolist(),
                   frames.dlc[ext].tolist(), frames.rx[ext].tolist(),
                   [bytes(r) for r in frames.data[ext].tolist()], strict=True)
        for t, can_id, dlc, rx, data in rows:
            fid = decode_id(int(can_id))
            out.append(IsobusFrame(t, fid.pgn, fid.source, fid.destination, data[:dlc],
                                   bool(rx)))
    else:
        for t, msg, rx in frames:  # type: ignore[misc]
            if not msg.is_extended_id or msg.is_error_frame or msg.is_remote_frame:
                continue
            fid = decode_id(msg.arbitration_id)
            out.append(IsobusFrame(float(t), fid.pgn, fid.source, fid.destination,
                                   bytes(msg.data), bool(rx)))
    out.sort(key=lambda f: f.time_s)
    return out


def _is_claim_request(f: IsobusFrame) -> bool:
    return f.pgn == PGN_REQUEST and len(f.data) >= 3 and \
        int.from_bytes(f.data[:3], "little") == PGN_ADDRESS_CLAIMED


def _claim_name(f: IsobusFrame) -> int | None:
    if f.pgn != PGN_ADDRESS_CLAIMED or len(f.data) < 8:
        return None
    return int.from_bytes(f.data[:8], "little")


def _counted(name: str, value: int, unit: str, limit: int, conditions: dict[str, Any] | None,
             kinds: Counter[str], examples: list[str]) -> Measurement:
    note = ", ".join(f"{k}: {n}" for k, n in sorted(kinds.items()))
    if examples:
        note += "; e.g. " + "; ".join(examples[:3])
    return Measurement(name, float(value), unit, high=float(limit),
                       conditions=dict(conditions or {}), note=note)


# -- address claim ----------------------------------------------------------------------------

@dataclass
class _Holding:
    """The DUT's hold on one address: claimed when, by which NAME, lost to whom."""

    name: int
    claimed_s: float
    lost_s: float | None = None
    winner: int | None = None


@dataclass
class ClaimTimeline:
    """What the log says about the DUT's claims: per address its hold, the DUT's NAMEs."""

    holdings: dict[int, _Holding] = field(default_factory=dict)
    names: set[int] = field(default_factory=set)
    before: Counter[str] = field(default_factory=Counter)
    before_examples: list[str] = field(default_factory=list)
    contention: Counter[str] = field(default_factory=Counter)
    contention_examples: list[str] = field(default_factory=list)


def claim_timeline(frames: Frames, *, resolution_s: float = 0.0) -> ClaimTimeline:
    """Walk the log once, following each address the DUT claims.

    A DUT frame (``rx``) from address A that is not an address claim counts as *before the
    claim* when the DUT has not claimed A, or claimed it less than 250 ms (minus
    ``resolution_s``) earlier; a repeated claim of an address the DUT holds (answering a
    request, defending) does not start the 250 ms again. Requests for the address-claimed PGN
    from the null address are allowed before a claim; any other DUT frame from 0xFE counts.
    When another NAME, lower than the DUT's, claims an address the DUT holds, the DUT has lost
    it: every DUT frame from it later than ``resolution_s`` after the contender's claim counts
    as *contention* (its own claims of it included) for the rest of the log (the contender
    keeps it). Requests for the address-claimed PGN are allowed at any time.
    """
    tl = ClaimTimeline()
    for f in isobus_frames(frames):
        name = _claim_name(f)
        if not f.rx:
            if name is None or f.source >= NULL_ADDRESS:
                continue
            hold = tl.holdings.get(f.source)
            if hold is not None and name not in tl.names and name < hold.name and \
                    (hold.winner is None or name < hold.winner):
                hold.winner = name
                if hold.lost_s is None:
                    hold.lost_s = f.time_s
            continue
        if name is not None:
            tl.names.add(name)
        hold = tl.holdings.get(f.source)
        lost = hold is not None and hold.lost_s is not None and \
            f.time_s > hold.lost_s + resolution_s
        if lost and hold is not None:
            kind = "claim of a lost address" if name is not None else "frame from a lost address"
            tl.contention[kind] += 1
            tl.contention_examples.append(
                f"PGN 0x{f.pgn:05X} from 0x{f.source:02X} at {f.time_s:.3f} s, lost at "
                f"{hold.lost_s:.3f} s to NAME 0x{hold.winner or 0:016X}")
            continue
        if name is not None:
            if f.source == NULL_ADDRESS:
                continue
            if hold is None or hold.name != name or hold.lost_s is not None:
                tl.holdings[f.source] = _Holding(name, f.time_s)
            continue
        if _is_claim_request(f):
            continue
        if f.source == NULL_ADDRESS:
            tl.before["from the null address"] += 1
            tl.before_examples.append(f"PGN 0x{f.pgn:05X} from 0xFE at {f.time_s:.3f} s")
        elif hold is None:
            tl.before["before any claim"] += 1
            tl.before_examples.append(f"PGN 0x{f.pgn:05X} from 0x{f.source:02X} at "
                                      f"{f.time_s:.3f} s, never claimed before")
        elif f.time_s < hold.claimed_s + CLAIM_WAIT_S - resolution_s - 1e-9:
            tl.before["within 250 ms of the claim"] += 1
            tl.before_examples.append(
                f"PGN 0x{f.pgn:05X} from 0x{f.source:02X} at {f.time_s:.3f} s, "
                f"{1000 * (f.time_s - hold.claimed_s):.0f} ms after its claim")
    return tl


def claim_frames_before(frames: Frames, *, resolution_s: float = 0.0,
                        conditions: dict[str, Any] | None = None) -> Measurement:
    """``isobus.claim.frames_before``: DUT frames before its claim or within 250 ms of it.

    See :func:`claim_timeline` for what counts. Limit :data:`FRAMES_BEFORE_CLAIM_LIMIT`.
    """
    tl = claim_timeline(frames, resolution_s=resolution_s)
    value = sum(tl.before.values())
    m = _counted("isobus.claim.frames_before", value, "frames", FRAMES_BEFORE_CLAIM_LIMIT,
                 conditions, tl.before, tl.before_examples)
    if not tl.names:
        return Measurement(m.name, m.value, m.unit, high=m.high, conditions=m.conditions,
                           note=(m.note + "; " if m.note else "") + "the DUT claimed no address")
    return m


def claim_contention(frames: Frames, *, resolution_s: float = 0.0,
                     conditions: dict[str, Any] | None = None) -> Measurement:
    """``isobus.claim.contention``: DUT frames from an address it lost to a lower NAME.

    See :func:`claim_timeline`. Limit :data:`CONTENTION_FRAMES_LIMIT`. The note says how many
    contentions the DUT lost (0: the measure says nothing about contention handling).
    """
    tl = claim_timeline(frames, resolution_s=resolution_s)
    lost = sum(1 for h in tl.holdings.values() if h.lost_s is not None)
    value = sum(tl.contention.values())
    m = _counted("isobus.claim.contention", value, "frames", CONTENTION_FRAMES_LIMIT,
                 conditions, tl.contention, tl.contention_examples)
    note = f"{lost} address(es) lost to a lower NAME" + (f"; {m.note}" if m.note else "")
    return Measurement(m.name, m.value, m.unit, high=m.high, conditions=m.conditions, note=note)


def claim_requests_unanswered(frames: Frames, *, resolution_s: float = 0.0,
                              conditions: dict[str, Any] | None = None) -> Measurement:
    """``isobus.claim.request_answered``: requests for the address-claimed PGN the DUT left
    unanswered.

    A request by another node (``rx`` False) to everyone, or to an address the DUT holds,
    after the DUT's first claim, must be answered by a claim carrying the DUT's NAME (from its
    address, or cannot-claim from 0xFE) within Tr = 200 ms (+ ``resolution_s``). Requests too
    close to the end of the log to tell are left out (the note says how many). Each DUT NAME
    seen before the request counts once per request. Limit
    :data:`UNANSWERED_REQUESTS_LIMIT`.
    """
    fs = isobus_frames(frames)
    end_s = fs[-1].time_s if fs else 0.0
    window = TR_S + resolution_s
    first_claim: dict[int, float] = {}
    holder: dict[int, int] = {}
    claims: list[tuple[int, float, int]] = []       # (log index, time, NAME)
    requests: list[tuple[int, float, int]] = []     # (log index, time, destination)
    for i, f in enumerate(fs):
        name = _claim_name(f)
        if f.rx and name is not None:
            first_claim.setdefault(name, f.time_s)
            claims.append((i, f.time_s, name))
            if f.source != NULL_ADDRESS:
                holder[f.source] = name
        elif not f.rx and _is_claim_request(f):
            requests.append((i, f.time_s, f.destination))
    asked = unanswered = late = 0
    examples: list[str] = []
    for index, t, dest in requests:
        names = sorted(first_claim) if dest == GLOBAL_ADDRESS else (
            [holder[dest]] if dest in holder else [])
        for name in names:
            if first_claim[name] > t:
                continue
            if t + window > end_s:
                late += 1
                continue
            asked += 1
            # an answer is a claim after the request in the log (at the same time stamp too)
            if not any(ci > index and ct <= t + window + 1e-9 and cn == name
                       for ci, ct, cn in claims):
                unanswered += 1
                examples.append(f"request at {t:.3f} s to 0x{dest:02X}, NAME 0x{name:016X}")
    kinds: Counter[str] = Counter({"unanswered": unanswered} if unanswered else {})
    m = _counted("isobus.claim.request_answered", unanswered, "requests",
                 UNANSWERED_REQUESTS_LIMIT, conditions, kinds, examples)
    note = (f"{asked} request(s) for the address-claimed PGN to the DUT, answer within "
            f"{1000 * window:g} ms" + (f"; {late} too close to the end of the log to judge"
                                       if late else "") + (f"; {m.note}" if m.note else ""))
    return Measurement(m.name, m.value, m.unit, high=m.high, conditions=m.conditions, note=note)


# -- transport --------------------------------------------------------------------------------

@dataclass
class _Session:
    protocol: str               # "BAM", "TP", "ETP"
    sender: int
    receiver: int
    sender_is_dut: bool
    size: int
    packets: int
    max_per_cts: int
    last_s: float
    waiting: str                # who waits now: "sender", "receiver", "" (nobody: closed)
    timeout_s: float
    allowed: int = 0            # packets the current CTS (or DPO) still allows
    next_seq: int = 1           # the sequence number expected next
    received: int = 0           # packets received so far (absolute)
    offset: int = 0             # ETP: the DPO's offset
    cts_next: int = 1           # ETP: the packet the last CTS asked for
    bam_last_s: float = 0.0
    pending: int = 0            # ETP: packets the last CTS allowed, until its DPO
    ctses: int = 0              # CTS frames for one packet or more so far


def transport_violations(frames: Frames, *, resolution_s: float = 0.0,
                         bam_min_s: float = BAM_MIN_INTERVAL_S,
                         conditions: dict[str, Any] | None = None) -> Measurement:
    """``isobus.transport.violations``: TP/ETP protocol errors of the DUT, by kind.

    Sessions in which one side is the DUT (``rx`` frames) are followed from their RTS or BAM.
    Counted against the DUT (the kind is in the note):

    - ``tp-size`` / ``etp-size``: a TP RTS or BAM for fewer than 9 or more than 1,785 bytes; an
      ETP RTS for 1,785 bytes or fewer (ISO 11783-3: ETP carries 1,786 and more);
    - ``data-without-cts``: a data packet with no session (but those within Tr plus
      ``resolution_s`` of an abort of their session: already in the DUT's transmit queue),
      before a CTS (``data-without-dpo``: after an ETP CTS, before its DPO), or after the
      packets a CTS allowed were all sent (``packets-beyond-cts``);
    - ``sequence``: a data packet whose sequence number is not the next one;
    - ``bam-too-fast`` / ``bam-too-slow``: a BAM packet less than ``bam_min_s`` (minus
      ``resolution_s``) or more than 200 ms (plus it) after the BAM or the previous packet;
    - ``cts-during-transfer``: the DUT as receiver sent a CTS while packets of the previous
      one were due; ``cts-beyond-limit``: it asked for more packets than the RTS allows or the
      message has; ``dpo-exceeds-cts``, ``dpo-offset``: an ETP DPO that does not fit its CTS;
    - ``missing-eoma``: the DUT received every packet and sent no EndOfMsgAck (nor abort)
      before the sender's T3;
    - ``not-closed``: a session in which the DUT was the side waiting (as sender for a CTS or
      the EndOfMsgAck, T3/T4; as receiver for data, T1/T2) stalled past that timeout plus Tr
      and ``resolution_s`` and nobody aborted it. Sessions the log ends on before that are not
      judged; a BAM has no aborts and is never ``not-closed``.

    Which side a session's receiver is: the DUT when it has sent from that address (any
    ``rx`` frame) by the time the session is judged.

    Limit :data:`TRANSPORT_VIOLATIONS_LIMIT`.
    """
    fs = isobus_frames(frames)
    end_s = fs[-1].time_s if fs else 0.0
    slack = TR_S + resolution_s
    kinds: Counter[str] = Counter()
    examples: list[str] = []
    sessions: dict[tuple[str, int, int], _Session] = {}
    judged = 0
    #: addresses the DUT has sent from: a session's receiver is the DUT if it is one of them
    dut_addresses: set[int] = set()
    #: when each session was aborted: the DUT's packets already queued may follow within Tr
    aborted: dict[tuple[str, int, int], float] = {}

    def flag(kind: str, f: IsobusFrame, what: str) -> None:
        kinds[kind] += 1
        examples.append(f"{kind} at {f.time_s:.3f} s: {what}")

    def expire(now: float) -> None:
        for key, s in list(sessions.items()):
            if s.protocol == "BAM":
                if now > s.last_s + T1_S + slack:
                    del sessions[key]
                continue
            if now <= s.last_s + s.timeout_s + slack:
                continue
            receiver_is_dut = s.receiver in dut_addresses
            waiter_is_dut = s.sender_is_dut if s.waiting in ("sender", "eoma") \
                else receiver_is_dut
            if s.waiting == "eoma" and not s.sender_is_dut and receiver_is_dut:
                kinds["missing-eoma"] += 1
                examples.append(f"missing-eoma: {s.protocol} of {s.size} B from "
                                f"0x{s.sender:02X}, last packet at {s.last_s:.3f} s")
            elif waiter_is_dut:
                kinds["not-closed"] += 1
                examples.append(f"not-closed: {s.protocol} 0x{s.sender:02X}->0x{s.receiver:02X}"
                                f" idle since {s.last_s:.3f} s, the DUT ({s.waiting}) sent no "
                                "abort")
            del sessions[key]

    for f in fs:
        expire(f.time_s)
        if f.rx and f.source < NULL_ADDRESS:
            dut_addresses.add(f.source)
        if f.pgn not in (PGN_TP_CM, PGN_TP_DT, PGN_ETP_CM, PGN_ETP_DT):
            continue
        etp = f.pgn in (PGN_ETP_CM, PGN_ETP_DT)
        proto = "ETP" if etp else "TP"
        if f.pgn in (PGN_TP_CM, PGN_ETP_CM):
            try:
                cm = decode_cm(f.data.ljust(8, b"\xff"), extended=etp)
            except FrameError as exc:
                if f.rx:
                    flag("bad-cm", f, str(exc))
                continue
            c = cm.control
            if c in (Control.RTS, Control.BAM, Control.ETP_RTS):
                bam = c == Control.BAM
                key = ("BAM" if bam else proto, f.source, f.destination)
                if f.rx and not etp and not 9 <= cm.size <= TP_MAX_BYTES:
                    flag("tp-size", f, f"{'BAM' if bam else 'RTS'} for {cm.size} B")
                if f.rx and etp and cm.size <= TP_MAX_BYTES:
                    flag("etp-size", f, f"ETP RTS for {cm.size} B")
                total = packets_for(cm.size)
                sessions[key] = _Session(key[0], f.source, f.destination, f.rx, cm.size,
                                         total, cm.max_per_cts if not etp else 255, f.time_s,
                                         "receiver" if bam else "sender", T1_S if bam else T3_S,
                                         bam_last_s=f.time_s)
                judged += 1
                if bam:
                    sessions[key].allowed = total
                continue
            if c == Control.ABORT:
                for key in ((proto, f.source, f.destination), (proto, f.destination, f.source)):
                    if sessions.pop(key, None) is not None:
                        aborted[key] = f.time_s
                continue
            # CTS / EOMA / DPO: CTS and EOMA go from the receiver to the sender
            if c in (Control.CTS, Control.ETP_CTS, Control.EOMA, Control.ETP_EOMA):
                key = (proto, f.destination, f.source)
            else:
                key = (proto, f.source, f.destination)
            s = sessions.get(key)
            if s is None:
                continue
            s.last_s = f.time_s
            if c in (Control.EOMA, Control.ETP_EOMA):
                del sessions[key]
                continue
            if c in (Control.CTS, Control.ETP_CTS):
                if f.rx and s.allowed > 0 and s.waiting == "receiver":
                    flag("cts-during-transfer", f, f"{s.allowed} packet(s) of the last CTS due")
                first = cm.next_packet
                if f.rx and cm.packets and (cm.packets > s.max_per_cts
                                            or first + cm.packets - 1 > s.packets or first < 1):
                    flag("cts-beyond-limit", f, f"CTS for {cm.packets} from {first}, message "
                         f"{s.packets} packets, at most {s.max_per_cts} per CTS")
                s.ctses += cm.packets > 0
                if cm.packets == 0:
                    s.allowed, s.waiting, s.timeout_s = 0, "sender", T4_S
                elif etp:
                    s.cts_next, s.allowed = first, 0
                    s.pending = cm.packets
                    s.waiting, s.timeout_s = "receiver", T2_S
                else:
                    s.allowed, s.next_seq = cm.packets, first
                    s.waiting, s.timeout_s = "receiver", T2_S
                continue
            if c == Control.ETP_DPO:
                pending = s.pending
                if f.rx and cm.packets > pending:
                    flag("dpo-exceeds-cts", f, f"DPO for {cm.packets}, the CTS allowed {pending}")
                if f.rx and cm.offset != s.cts_next - 1:
                    flag("dpo-offset", f, f"offset {cm.offset}, the CTS asked for packet "
                         f"{s.cts_next}")
                s.offset, s.allowed, s.next_seq = cm.offset, cm.packets, 1
                s.pending = 0
                s.waiting, s.timeout_s = "receiver", T1_S
                continue
            continue
        # data packets go from the sender to the receiver
        dest = f.destination
        s = sessions.get(("BAM" if dest == GLOBAL_ADDRESS else proto, f.source, dest))
        if s is None:
            gone = aborted.get((proto, f.source, dest))
            if f.rx and (gone is None or f.time_s > gone + slack):
                flag("data-without-cts", f, f"{proto}.DT 0x{f.source:02X}->0x{dest:02X} with no "
                     "session")
            continue
        seq = f.data[0] if f.data else -1
        if s.protocol == "BAM":
            gap = f.time_s - s.bam_last_s
            if f.rx and gap < bam_min_s - resolution_s - 1e-9:
                flag("bam-too-fast", f, f"{1000 * gap:.1f} ms after the previous frame "
                     f"(at least {1000 * bam_min_s:g} ms)")
            elif f.rx and gap > BAM_MAX_INTERVAL_S + resolution_s + 1e-9:
                flag("bam-too-slow", f, f"{1000 * gap:.1f} ms after the previous frame")
            s.bam_last_s = f.time_s
        if f.rx:
            if s.allowed <= 0 and s.protocol != "BAM":
                kind = ("data-without-dpo" if s.pending else
                        "packets-beyond-cts" if s.ctses else "data-without-cts")
                flag(kind, f, f"{proto}.DT seq {seq} to 0x{dest:02X}")
            elif seq != s.next_seq:
                flag("sequence", f, f"seq {seq}, {s.next_seq} expected")
        s.last_s = f.time_s
        s.allowed -= 1
        s.next_seq = seq + 1
        s.received = (s.offset + seq) if s.protocol == "ETP" else seq
        if s.protocol == "BAM":
            if s.received >= s.packets:
                del sessions[("BAM", f.source, dest)]
            continue
        if s.received >= s.packets and s.allowed <= 0:
            s.waiting, s.timeout_s = "eoma", T3_S
        elif s.allowed <= 0:
            s.waiting, s.timeout_s = "sender", T3_S
        else:
            s.waiting, s.timeout_s = "receiver", T1_S
    # sessions left open at the end: judged only if their deadline lies within the log
    expire(end_s)
    value = sum(kinds.values())
    m = _counted("isobus.transport.violations", value, "violations", TRANSPORT_VIOLATIONS_LIMIT,
                 conditions, kinds, examples)
    note = f"{judged} TP/ETP session(s) followed" + (f"; {m.note}" if m.note else "")
    return Measurement(m.name, m.value, m.unit, high=m.high, conditions=m.conditions, note=note)


# -- rates ------------------------------------------------------------------------------------

def pgn_rates(frames: Frames, *, declared: Iterable[CyclicPgn] = ISOBUS_CYCLIC,
              resolution_s: float = 0.0,
              conditions: dict[str, Any] | None = None) -> list[Measurement]:
    """``isobus.pgn.rate``: per declared cyclic message the DUT sends (single frames), the
    median interval's deviation from the declared period in %, limits
    +/- :data:`PGN_RATE_TOLERANCE_PCT`.

    Intervals are taken per source address (a DUT that moved address starts anew). A message
    the DUT sends fewer than twice gives no measurement: it is not cyclic in this run (the TC
    client task only runs while connected), and whether it should have been is another
    measurement's business.
    """
    fs = [f for f in isobus_frames(frames) if f.rx]
    out: list[Measurement] = []
    for spec in declared:
        times = [(f.source, f.time_s) for f in fs if f.pgn == spec.pgn and
                 (spec.first_byte is None or (f.data and f.data[0] == spec.first_byte))]
        gaps: list[float] = []
        by_source: dict[int, float] = {}
        for source, t in times:
            if source in by_source:
                gaps.append(t - by_source[source])
            by_source[source] = t
        if not gaps:
            continue
        stats = cycle_stats(np.array(gaps), spec.period_ms, -PGN_RATE_TOLERANCE_PCT,
                            PGN_RATE_TOLERANCE_PCT, 1000.0 * resolution_s)
        out.append(Measurement(
            "isobus.pgn.rate", stats.deviation_pct, "%", low=-PGN_RATE_TOLERANCE_PCT,
            high=PGN_RATE_TOLERANCE_PCT,
            conditions={"message": spec.label, "pgn": f"0x{spec.pgn:05X}", **(conditions or {})},
            note=(f"median {stats.median_ms:.4g} ms, min {stats.min_ms:.4g}, max "
                  f"{stats.max_ms:.4g} over {stats.count} intervals; declared "
                  f"{spec.period_ms:g} ms ({spec.source})")))
    return out


def isobus_conformance(frames: Frames, *, resolution_s: float = 0.0,
                       bam_min_s: float = BAM_MIN_INTERVAL_S,
                       declared: Iterable[CyclicPgn] = ISOBUS_CYCLIC,
                       conditions: dict[str, Any] | None = None) -> list[Measurement]:
    """All the ISOBUS measurements of one run, in a fixed order (claim, transport, rates)."""
    rows = isobus_frames(frames)
    kw: dict[str, Any] = {"resolution_s": resolution_s, "conditions": conditions}
    return [claim_frames_before(rows, **kw), claim_requests_unanswered(rows, **kw),
            claim_contention(rows, **kw),
            transport_violations(rows, bam_min_s=bam_min_s, **kw),
            *pgn_rates(rows, declared=declared, **kw)]


__all__ = [
    "BAM_MIN_INTERVAL_S", "CONTENTION_FRAMES_LIMIT", "FRAMES_BEFORE_CLAIM_LIMIT",
    "ISOBUS_CYCLIC", "PGN_RATE_TOLERANCE_PCT", "TRANSPORT_VIOLATIONS_LIMIT",
    "UNANSWERED_REQUESTS_LIMIT", "CyclicPgn", "IsobusFrame", "claim_contention",
    "claim_frames_before", "claim_requests_unanswered", "claim_timeline", "isobus_conformance",
    "isobus_frames", "pgn_rates", "transport_violations",
]
