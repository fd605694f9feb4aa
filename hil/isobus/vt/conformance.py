"""A VT client's behaviour on the bus, judged from the frames (ISO 11783-6).

:func:`vt_client_findings` reads a run's frames (sent and received, in time order) and lists,
for every working set that talks to the VT at ``vt_address``:

- ``maintenance``: a gap between two working set maintenance messages longer than
  :data:`MAINTENANCE_LATE_S` (the message is due every second; the VT drops a working set
  silent for 3 s, so 1.5 s is half a period late, with room before the VT acts);
- ``pool-before-memory``: an object pool transfer before the working set asked for memory
  (the connection procedure asks first);
- ``two-transfers``: a TP or ETP transfer to the VT started while another of the same
  working set to it was still open (one transfer at a time).

Only what the frames show is judged: a transfer's first byte (its function) is read from its
first data packet; a transfer whose packets were not seen is taken as a pool transfer when it
is an ETP one.

:func:`vt_client_conformance` makes them the measurements of a qualification's bus conformance
(``isobus.vt_client.violations``, one per kind, limit 0), for a run that had a VT on the bus
(its status heard). A maintenance gap while the VT itself was silent (its status more than
1.5 s apart: a VT restart) is the VT's, not the client's: a client stops its maintenance when
it has lost the VT (3 s without status) and starts over when it is back.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import can

from hil.isobus.can_id import decode_id, encode_id
from hil.isobus.tp_messages import PGN_ETP_CM, PGN_ETP_DT, PGN_TP_CM, PGN_TP_DT, Control
from hil.isobus.vt.messages import ECU_TO_VT_PGN, VT_TO_ECU_PGN, Function
from hil.measurements import Measurement

MAINTENANCE_PERIOD_S = 1.0
MAINTENANCE_LATE_S = 1.5
"""A gap between two maintenance messages beyond this is a finding."""


@dataclass(frozen=True)
class Finding:
    """One breach by one working set."""

    time_s: float
    address: int
    kind: str
    detail: str
    #: a maintenance gap's start (its end is ``time_s``)
    since_s: float | None = None


@dataclass
class _Client:
    last_maintenance_s: float | None = None
    asked_memory: bool = False
    open_since_s: float | None = None
    open_protocol: str = ""
    pending_function: int | None = None


def vt_client_findings(frames: Iterable[tuple[float, can.Message]],
                       vt_address: int = 0x26, end_s: float | None = None) -> list[Finding]:
    """The findings (see the module docstring), in time order.

    ``end_s``: the run's end; a working set whose maintenance stopped more than
    :data:`MAINTENANCE_LATE_S` before it is found late once (it stopped keeping itself alive).
    """
    clients: dict[int, _Client] = {}
    findings: list[Finding] = []
    for time_s, msg in frames:
        if not msg.is_extended_id or msg.is_error_frame:
            continue
        fid = decode_id(msg.arbitration_id)
        data = bytes(msg.data)
        if fid.destination == vt_address and fid.source != vt_address:
            client = clients.setdefault(fid.source, _Client())
            if fid.pgn == ECU_TO_VT_PGN and data:
                _single(client, fid.source, data[0], time_s, findings)
            elif fid.pgn in (PGN_TP_CM, PGN_ETP_CM) and data:
                _connection(client, fid.source, fid.pgn, data, time_s, findings)
            elif fid.pgn in (PGN_TP_DT, PGN_ETP_DT) and len(data) >= 2 and data[0] == 1 \
                    and client.pending_function is None and client.open_since_s is not None:
                client.pending_function = data[1]       # the transfer's first byte
                _function(client, fid.source, data[1], time_s, findings)
        elif fid.source == vt_address and fid.pgn in (PGN_TP_CM, PGN_ETP_CM) and data:
            client = clients.get(fid.destination)
            if client is not None and data[0] in (Control.EOMA, Control.ETP_EOMA,
                                                  Control.ABORT):
                client.open_since_s = None
                client.pending_function = None
    if end_s is not None:
        for address, client in clients.items():
            last = client.last_maintenance_s
            if last is not None and end_s - last > MAINTENANCE_LATE_S:
                findings.append(Finding(end_s, address, "maintenance",
                                        f"no working set maintenance for the last "
                                        f"{end_s - last:.1f} s of the run", since_s=last))
    return sorted(findings, key=lambda f: f.time_s)


def _single(client: _Client, address: int, function: int, t: float,
            findings: list[Finding]) -> None:
    if function == Function.WORKING_SET_MAINTENANCE:
        last = client.last_maintenance_s
        if last is not None and t - last > MAINTENANCE_LATE_S:
            findings.append(Finding(t, address, "maintenance",
                                    f"{t - last:.2f} s between two working set maintenance "
                                    f"messages (due every {MAINTENANCE_PERIOD_S:g} s)",
                                    since_s=last))
        client.last_maintenance_s = t
    _function(client, address, function, t, findings)


def _function(client: _Client, address: int, function: int, t: float,
              findings: list[Finding]) -> None:
    if function == Function.GET_MEMORY:
        client.asked_memory = True
    elif function == Function.OBJECT_POOL_TRANSFER and not client.asked_memory:
        findings.append(Finding(t, address, "pool-before-memory",
                                "object pool transfer before get memory"))
        client.asked_memory = True      # found once


def _connection(client: _Client, address: int, pgn: int, data: bytes, t: float,
                findings: list[Finding]) -> None:
    control = data[0]
    if control in (Control.RTS, Control.ETP_RTS):
        if len(data) >= 8 and int.from_bytes(data[5:8], "little") != ECU_TO_VT_PGN:
            return
        protocol = "TP" if control == Control.RTS else "ETP"
        if client.open_since_s is not None:
            findings.append(Finding(t, address, "two-transfers",
                                    f"{protocol} transfer started while a {client.open_protocol} "
                                    f"transfer opened at {client.open_since_s:.2f} s was "
                                    f"still open"))
        client.open_since_s = t
        client.open_protocol = protocol
        client.pending_function = None
        if protocol == "ETP" and not client.asked_memory:
            # an ETP transfer to the VT is an object pool's (nothing else is that long)
            _function(client, address, Function.OBJECT_POOL_TRANSFER, t, findings)
            client.pending_function = Function.OBJECT_POOL_TRANSFER
    elif control == Control.ABORT:
        client.open_since_s = None
        client.pending_function = None


# -- in a qualification's bus conformance -----------------------------------------------------

KINDS = ("maintenance", "pool-before-memory", "two-transfers")
"""What :func:`vt_client_findings` finds, each a measurement of its own."""
VT_STATUS = 0xFE
"""The VT status message's function byte."""
VT_SILENT_S = 1.5
"""VT status messages (every 1 s) further apart than this: the VT was silent (restarting)."""
MEASUREMENT = "isobus.vt_client.violations"


class FrameRow(Protocol):
    """A decoded 29-bit frame (:class:`hil.conformance.isobus.IsobusFrame`)."""

    time_s: float
    pgn: int
    source: int
    destination: int
    data: bytes


def vt_silences(rows: Sequence[FrameRow], vt_address: int,
                end_s: float | None = None) -> list[tuple[float, float]]:
    """(from, to) where the VT's status messages were more than :data:`VT_SILENT_S` apart
    (to the end of the run when it ended silent)."""
    status = [r.time_s for r in rows if r.source == vt_address and r.pgn == VT_TO_ECU_PGN
              and r.data[:1] == bytes([VT_STATUS])]
    out = [(a, b) for a, b in itertools.pairwise(status) if b - a > VT_SILENT_S]
    if status and end_s is not None and end_s - status[-1] > VT_SILENT_S:
        out.append((status[-1], end_s))
    return out


def vt_client_conformance(rows: Sequence[FrameRow], *, vt_address: int = 0x26,
                          end_s: float | None = None,
                          conditions: dict[str, Any] | None = None) -> list[Measurement]:
    """``isobus.vt_client.violations`` per kind, limit 0, for a run whose frames show the VT's
    status (none otherwise: no VT, nothing to judge); maintenance gaps across the VT's own
    silence are left out (see the module docstring)."""
    silences = vt_silences(rows, vt_address, end_s)
    if not any(r.source == vt_address and r.pgn == VT_TO_ECU_PGN for r in rows):
        return []
    frames = [(r.time_s, can.Message(arbitration_id=encode_id(6, r.pgn, r.source,
                                                               r.destination),
                                     is_extended_id=True, data=r.data)) for r in rows]
    found = [f for f in vt_client_findings(frames, vt_address, end_s)
             if not (f.kind == "maintenance" and f.since_s is not None
                     and any(a < f.time_s and f.since_s < b for a, b in silences))]
    excused = len(silences)
    out = []
    for kind in KINDS:
        mine = [f for f in found if f.kind == kind]
        shown = "; ".join(f"{f.time_s:.2f} s from 0x{f.address:02X}: {f.detail}"
                          for f in mine[:5])
        note = shown + (f" (and {len(mine) - 5} more)" if len(mine) > 5 else "")
        if kind == "maintenance" and excused:
            note = (note + "; " if note else "") + (f"gaps across the VT's {excused} "
                                                    f"silence(s) left out")
        out.append(Measurement(MEASUREMENT, float(len(mine)), "findings",
                               conditions={**(conditions or {}), "kind": kind}, note=note,
                               high=0.0))
    return out
