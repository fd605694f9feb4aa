"""What the DUT may send, from its databases: the bus contract a run is checked against.

Declared frames of the DUT (node id ``n`` from the profile's wiring):

* every DBC message whose sender is the DUT's node (named by the DBC message carrying the
  heartbeat 0x700 + n, else by the rig), with the DBC's length and ``GenMsgCycleTime``;
* its CANopen services (CiA 301): boot-up and heartbeat 0x700 + n, EMCY 0x080 + n, SDO
  answers 0x580 + n;
* towards each CANopen node the rig plays (its EDS, through canopen): the node's RPDOs (length
  of their mapping) and SDO requests 0x600 + node; NMT commands (0x000) where the rig makes the
  DUT the nodes' NMT master;
* the frames it sends on SYNC (the profile's ``wiring.command_ids``, else the rig's) are
  cyclic at the profile's control period, whatever the DBC says.

The heartbeat is judged against the profile's ``timing.heartbeat_period_ms``, and against the
consumer heartbeat time (object 0x1016) of every rig node whose EDS watches the DUT's node.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import canopen
import cantools

from hil.conformance.rigs import RigBus
from hil.errors import ConfigError

#: a frame's identity on the bus: (identifier, 29-bit)
FrameKey = tuple[int, bool]


@dataclass(frozen=True)
class DeclaredFrame:
    """One frame the DUT may send.

    Attributes
    ----------
    name : str
        The DBC message name, or the CANopen service (``Heartbeat``, ``EMCY``, ``RPDO2 of
        servo drive`` …).
    can_id, extended, dlc : int, bool, int
        Identifier, 29-bit or not, declared data length.
    cycle_ms : float or None
        Declared period; None for event frames (boot-up, EMCY, SDO, acyclic PDOs).
    source : str
        Where it is declared (``fertilizer.dbc``, ``CiA 301``, ``servo_cylinder_cia402.eds``).
    cycle_source : str
        Where the period comes from (``GenMsgCycleTime``, ``timing.control_period_ms (SYNC)``).
    note : str
        A disagreement worth showing (a DBC cycle time that differs from the SYNC period).
    """

    name: str
    can_id: int
    extended: bool
    dlc: int
    cycle_ms: float | None = None
    source: str = ""
    cycle_source: str = ""
    note: str = ""

    @property
    def key(self) -> FrameKey:
        return (self.can_id, self.extended)

    @property
    def label(self) -> str:
        width = 8 if self.extended else 3
        return f"0x{self.can_id:0{width}X}"


@dataclass(frozen=True)
class Consumer:
    """A rig node that consumes the DUT's heartbeat (0x1016) and its time."""

    name: str
    time_ms: float


@dataclass(frozen=True)
class BusContract:
    """Everything a run of one DUT is checked against."""

    node_name: str
    node_id: int
    frames: dict[FrameKey, DeclaredFrame]
    heartbeat_period_ms: float
    control_period_ms: float
    command_ids: frozenset[int]
    bitrate_bps: int
    consumers: tuple[Consumer, ...] = ()
    databases: tuple[str, ...] = field(default=())

    @property
    def heartbeat_id(self) -> int:
        return 0x700 + self.node_id


@lru_cache(maxsize=16)
def _load_dbc(path: str, mtime_ns: int) -> cantools.database.can.Database:
    del mtime_ns        # part of the cache key only: an edited file is read again
    return cantools.database.load_file(path)


@lru_cache(maxsize=16)
def _eds(path: str, node_id: int, mtime_ns: int) -> tuple[tuple[tuple[int, int, int], ...],
                                                          tuple[tuple[int, int], ...]]:
    """(RPDO cob id, length in bytes, transmission type) of every enabled RPDO, and the
    consumer heartbeat entries (node id, time ms) of 0x1016."""
    del mtime_ns
    od = canopen.import_od(path, node_id)
    rpdos = []
    for number in range(512):
        comm, mapping = 0x1400 + number, 0x1600 + number
        if comm not in od or mapping not in od:
            continue
        cob = int(od[comm][1].default or 0)
        if cob & 0x80000000 or not cob:
            continue                    # not valid (CiA 301 bit 31)
        trans = int(od[comm][2].default) if 2 in od[comm] else 255
        count = int(od[mapping][0].default or 0)
        bits = sum(int(od[mapping][sub].default or 0) & 0xFF for sub in range(1, count + 1))
        rpdos.append((cob & 0x1FFFFFFF, bits // 8, trans))
    consumers = []
    if 0x1016 in od:
        entries = int(od[0x1016][0].default or 0)
        for sub in range(1, entries + 1):
            if sub in od[0x1016]:
                value = int(od[0x1016][sub].default or 0)
                if value & 0xFFFF:
                    consumers.append(((value >> 16) & 0x7F, value & 0xFFFF))
    return tuple(rpdos), tuple(consumers)


def _mtime(path: Path, what: str) -> int:
    try:
        return path.stat().st_mtime_ns
    except OSError as exc:
        raise ConfigError(f"{what} not found: {exc.strerror or exc}", path=str(path)) from exc


def build_contract(rig: RigBus, *, node_id: int, heartbeat_period_ms: float,
                   control_period_ms: float, command_ids: frozenset[int] = frozenset(),
                   database: Path | None = None) -> BusContract:
    """The DUT's bus contract from the rig's databases and the profile's wiring and timing.

    Parameters
    ----------
    rig : RigBus
        The rig's databases.
    node_id : int
        The DUT's CANopen node id.
    heartbeat_period_ms, control_period_ms : float
        The profile's timing.
    command_ids : frozenset of int
        Frames sent once per control period (empty: the rig's).
    database : Path, optional
        The profile's ``wiring.database`` (default: the rig's DBC).

    Raises
    ------
    ConfigError
        A database that cannot be read (the file is named).
    """
    dbc_path = database or rig.dbc
    try:
        db = _load_dbc(str(dbc_path), _mtime(dbc_path, "message database"))
    except ConfigError:
        raise
    except Exception as exc:    # cantools raises its own and built-in errors
        raise ConfigError(f"cannot read the message database: {exc}",
                          path=str(dbc_path)) from exc
    heartbeat_id = 0x700 + node_id
    node = next((m.senders[0] for m in db.messages if m.frame_id == heartbeat_id
                 and not m.is_extended_frame and m.senders), rig.dut_node)
    sync_driven = command_ids or rig.command_ids
    frames: dict[FrameKey, DeclaredFrame] = {}
    for m in db.messages:
        if node not in m.senders:
            continue
        key = (m.frame_id, bool(m.is_extended_frame))
        cycle = float(m.cycle_time) if m.cycle_time else None
        declared = DeclaredFrame(m.name, m.frame_id, bool(m.is_extended_frame), m.length,
                                 cycle, dbc_path.name, "GenMsgCycleTime" if cycle else "")
        frames[key] = _on_sync(declared, sync_driven, control_period_ms)
    for name, can_id, dlc in (("Heartbeat", heartbeat_id, 1), ("EMCY", 0x80 + node_id, 8),
                              ("SDO answer", 0x580 + node_id, 8)):
        frames.setdefault((can_id, False), DeclaredFrame(name, can_id, False, dlc, None,
                                                         "CiA 301"))
    if rig.dut_is_nmt_master and rig.canopen_nodes:
        frames.setdefault((0x000, False), DeclaredFrame("NMT command", 0x000, False, 2, None,
                                                        "CiA 301 (NMT master)"))
    consumers = []
    for device in rig.canopen_nodes:
        rpdos, consumed = _eds(str(device.eds), device.node_id, _mtime(device.eds, "EDS"))
        for number, (cob, dlc, _trans) in enumerate(rpdos, 1):
            declared = DeclaredFrame(f"RPDO{number} of {device.name}", cob, False, dlc, None,
                                     device.eds.name)
            frames.setdefault((cob, False), _on_sync(declared, sync_driven, control_period_ms))
        sdo = 0x600 + device.node_id
        frames.setdefault((sdo, False), DeclaredFrame(f"SDO request to {device.name}", sdo,
                                                      False, 8, None, "CiA 301"))
        consumers += [Consumer(device.name, float(ms)) for watched, ms in consumed
                      if watched == node_id]
    heartbeat = frames[(heartbeat_id, False)]
    frames[(heartbeat_id, False)] = DeclaredFrame(
        heartbeat.name, heartbeat_id, False, 1, heartbeat_period_ms, heartbeat.source,
        "timing.heartbeat_period_ms",
        _disagrees(heartbeat.cycle_ms, heartbeat_period_ms, "heartbeat_period_ms"))
    return BusContract(node_name=node, node_id=node_id, frames=frames,
                       heartbeat_period_ms=heartbeat_period_ms,
                       control_period_ms=control_period_ms, command_ids=frozenset(sync_driven),
                       bitrate_bps=rig.bitrate_bps, consumers=tuple(consumers),
                       databases=(str(dbc_path), *(str(d.eds) for d in rig.canopen_nodes)))


def _on_sync(frame: DeclaredFrame, sync_driven: frozenset[int],
             control_period_ms: float) -> DeclaredFrame:
    """A frame sent on SYNC is cyclic at the control period (the DBC's cycle time, if it
    says otherwise, is noted)."""
    if frame.extended or frame.can_id not in sync_driven:
        return frame
    return DeclaredFrame(frame.name, frame.can_id, frame.extended, frame.dlc,
                         control_period_ms, frame.source, "timing.control_period_ms (SYNC)",
                         _disagrees(frame.cycle_ms, control_period_ms, "control_period_ms"))


def _disagrees(dbc_ms: float | None, profile_ms: float, what: str) -> str:
    if dbc_ms is None or abs(dbc_ms - profile_ms) < 1e-9:
        return ""
    return f"the database says {dbc_ms:g} ms, the profile's {what} {profile_ms:g} ms"
