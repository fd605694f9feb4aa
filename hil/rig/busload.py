"""Bus load: other ECUs' traffic on the rig's bus, so a DUT is tested on a bus near its bit rate.

A tractor's ISOBUS carries far more than the planter's frames: engine, transmission, hitch,
terminal and task-controller traffic. :class:`BusLoad` joins the rig's bus as one more node and
sends a fixed mix of 29-bit J1939-style frames (8 data bytes) with python-can's periodic
sends, at periods chosen so that the mix alone occupies ``fraction`` of the bit rate on the wire
(bit counts with stuffing, :func:`hil.softbus.timing.frame_bits`). Half of the load is at
priority 1, whose base identifier (the 11 bits arbitration compares first, 0x13C-0x13F)
outranks every rig and DUT frame but SYNC (0x080) and EMCY: the DUT's command (0x220), the
sensors' reports and the rig's priority-3 J1939 frames (base 0x33C and up) wait behind it in
arbitration, as behind a busy tractor's traffic. The other half is at priority 6 and waits
behind them.

Only a bus with a bit rate makes load mean anything: the software bus paced at the rig's
bit rate, or a physical bus. The runner refuses lockstep (virtual time has no wire) and buses
without a bit rate (``virtual``, ``inline``, kernel ``vcan``).
"""

from __future__ import annotations

from dataclasses import dataclass

import can

from hil.softbus.timing import frame_bits

#: (arbitration id, share of the load): PGN 0xF004 (engine) and 0xFE49 (hitch) at priority 1,
#: 0xFF10 and 0xFF20 (proprietary B) at priority 6, each from its own source address
LOAD_MIX: tuple[tuple[int, float], ...] = (
    (0x04F00400, 0.25), (0x04FE4921, 0.25), (0x18FF1080, 0.25), (0x18FF2081, 0.25))
DATA = bytes([0x55] * 8)   # alternating bits: no stuff bits in the data field


@dataclass(frozen=True)
class LoadFrame:
    """One frame of a bus load: its identifier, how often it is sent and its length on the wire.

    Parameters
    ----------
    arbitration_id : int
        The 29-bit identifier.
    period_s : float
        The period of its periodic send, in seconds.
    bits : int
        Its length on the wire in bits, stuff bits included.
    """

    arbitration_id: int
    period_s: float
    bits: int


def load_schedule(fraction: float, bitrate_bps: int,
                  mix: tuple[tuple[int, float], ...] = LOAD_MIX) -> list[LoadFrame]:
    """The frames and periods that occupy ``fraction`` of ``bitrate_bps`` on the wire.

    Parameters
    ----------
    fraction : float
        The share of the bit rate to occupy, in (0, 1).
    bitrate_bps : int
        The bus's bit rate.
    mix : tuple of (int, float), optional
        (29-bit identifier, share of the load) pairs; default :data:`LOAD_MIX`.

    Returns
    -------
    list of LoadFrame
        One entry per identifier of ``mix``.

    Raises
    ------
    ValueError
        ``fraction`` is not in (0, 1) or the bit rate is not positive.
    """
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"bus load fraction must be in (0, 1), got {fraction}")
    if bitrate_bps <= 0:
        raise ValueError(f"bit rate must be positive, got {bitrate_bps}")
    total_share = sum(share for _, share in mix)
    schedule = []
    for can_id, share in mix:
        bits = frame_bits(can_id, True, DATA)
        bits_per_s = fraction * bitrate_bps * share / total_share
        schedule.append(LoadFrame(can_id, bits / bits_per_s, bits))
    return schedule


def offered_load(schedule: list[LoadFrame], bitrate_bps: int) -> float:
    """Fraction of the bit rate the schedule offers."""
    return sum(f.bits / f.period_s for f in schedule) / bitrate_bps


class BusLoad:
    """A load node on ``bus``: other ECUs' periodic traffic at a share of the bit rate.

    ``bus`` is a python-can bus of its own (the rig's frames are not its business). A context
    manager: the periodic sends start on entry and stop on exit.

    Parameters
    ----------
    bus : can.BusABC
        The node's own connection to the rig's bus.
    fraction : float
        The share of the bit rate the load occupies, in (0, 1).
    bitrate_bps : int
        The bus's bit rate.
    """

    def __init__(self, bus: can.BusABC, fraction: float, bitrate_bps: int) -> None:
        self.bus = bus
        self.schedule = load_schedule(fraction, bitrate_bps)
        self.fraction = fraction
        self.bitrate_bps = bitrate_bps
        self._tasks: list[can.broadcastmanager.CyclicSendTaskABC] = []

    def start(self) -> BusLoad:
        """Start one periodic send per frame of the schedule.

        Returns
        -------
        BusLoad
            This node.
        """
        for frame in self.schedule:
            msg = can.Message(arbitration_id=frame.arbitration_id, is_extended_id=True,
                              data=DATA)
            self._tasks.append(self.bus.send_periodic(msg, frame.period_s, store_task=False))
        return self

    def stop(self) -> None:
        """Stop every periodic send and wait for its thread.

        python-can's ``stop`` only flags it, and a send after the bus is shut down fails in that
        thread.
        """
        for task in self._tasks:
            task.stop()
        for task in self._tasks:
            thread = getattr(task, "thread", None)
            if thread is not None:
                thread.join(timeout=2.0)
        self._tasks.clear()

    def describe(self) -> dict[str, object]:
        """For the record: what was offered, frame by frame."""
        return {"fraction": self.fraction, "bitrate_bps": self.bitrate_bps,
                "offered": round(offered_load(self.schedule, self.bitrate_bps), 4),
                "frames": [{"id": f"0x{f.arbitration_id:08X}", "period_ms":
                            round(f.period_s * 1e3, 3), "bits": f.bits}
                           for f in self.schedule]}

    def __enter__(self) -> BusLoad:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def wire_load(log_path: str, bitrate_bps: int, t0: float | None = None,
              t1: float | None = None) -> float:
    """Fraction of the bit rate the frames of a bus log occupied between ``t0`` and ``t1``.

    Parameters
    ----------
    log_path : str
        A bus log python-can reads (``.asc``, ``.blf``, ...).
    bitrate_bps : int
        The bus's bit rate.
    t0, t1 : float, optional
        The window in log timestamps; default: the first and the last frame.

    Returns
    -------
    float
        Bits of the frames in the window (stuff bits included, error frames left out) over the
        bits the window could carry; 0 for fewer than two frames or an empty window.
    """
    stamps_bits = [(msg.timestamp, frame_bits(msg.arbitration_id, msg.is_extended_id,
                                              bytes(msg.data)))
                   for msg in can.LogReader(log_path) if not msg.is_error_frame]
    if len(stamps_bits) < 2:
        return 0.0
    lo = stamps_bits[0][0] if t0 is None else t0
    hi = stamps_bits[-1][0] if t1 is None else t1
    bits = sum(b for t, b in stamps_bits if lo <= t <= hi)
    return bits / bitrate_bps / (hi - lo) if hi > lo else 0.0
