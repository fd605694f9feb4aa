"""A CANopen slave node the rig plays, on canopen's ``LocalNode`` and the device's EDS.

canopen supplies the object dictionary, the SDO server and NMT; what ``LocalNode`` does not do
(see the project's measurements) is done here, scheduled by the rig's clock rather than by
canopen's wall-clock threads so it works in lockstep:

* heartbeats at the period in 0x1017 (canopen would start a ``send_periodic`` thread);
* TPDOs on SYNC (transmission types 1-240, every n-th SYNC) and on their event timer (254/255);
* received RPDOs written into the object dictionary (``set_data``, so write callbacks fire); one
  shorter than its mapping is dropped with EMCY 0x8210, a longer one is used with EMCY 0x8220;
* the master's configuration by SDO (:mod:`hil.rig.canopen_config`): PDO communication and
  mapping parameters, SYNC and EMCY COB-IDs, heartbeat producer and consumer times are checked
  against the EDS and CiA 301 before they are stored (a refusal is an SDO abort with its code)
  and take effect once stored: new COB-IDs, mappings, transmission types, event timers,
  inhibit times, heartbeat period and SYNC COB-ID;
* the error state of CiA 301 (:mod:`hil.rig.canopen_errors`): 0x1001 error register, 0x1003
  pre-defined error field (if the EDS declares it), EMCY on COB-ID 0x1014 when an error occurs
  and the error-reset EMCY (code 0x0000) when it goes away, spaced by the inhibit time 0x1015
  if the EDS declares it. EMCYs go out at the next SYNC or heartbeat/event time after the
  error, in pre-operational and operational; in stopped they wait until the node leaves it;
* NMT state rules: PDOs (SYNC, RPDOs, TPDOs) only in operational; SDO in pre-operational and
  operational; stopped answers NMT only and sends its heartbeat; reset node and reset
  communication send a boot-up message and go pre-operational (operational with autostart).

Frames canopen wants to send (SDO responses, say) are collected by :class:`OutboxNetwork`, a
``canopen.Network`` whose ``send_message`` appends to an outbox instead of touching a bus: the
documented way to put canopen on a custom backend. The runner sends them, so they are logged.
"""

from __future__ import annotations

import math
import pickle
import struct
from collections.abc import Callable, Collection
from pathlib import Path
from typing import Any

import can
import canopen
from canopen.objectdictionary import ODVariable
from canopen.objectdictionary.datatypes import INTEGER_TYPES, SIGNED_TYPES
from canopen.pdo.base import PdoMap

from hil.rig.canopen_config import CommunicationGuard, ConfigRefused
from hil.rig.canopen_errors import (
    ABORT_NO_DATA,
    ABORT_VALUE_RANGE,
    ErrorRegister,
    ErrorState,
    emcy_payload,
)
from hil.rig.device import Device

NMT_STATES = {"INITIALISING": 0x00, "STOPPED": 0x04, "OPERATIONAL": 0x05,
              "PRE-OPERATIONAL": 0x7F}
SYNC_ID = 0x080
#: EMCY error codes of CiA 301: PDO not processed due to length error / PDO length exceeded
PDO_LENGTH_ERROR = 0x8210
PDO_LENGTH_EXCEEDED = 0x8220

#: objects whose writes change how the node communicates (re-read once an SDO write is stored)
_COMMUNICATION_OBJECTS = (0x1005, 0x1014, 0x1016, 0x1017)


def _is_communication(index: int) -> bool:
    return index in _COMMUNICATION_OBJECTS or 0x1400 <= index <= 0x1BFF


#: a byte-aligned PDO map's variables as (variable, index, subindex, first byte, end byte, OD
#: entry, packer, lowest, highest) (a map that is not byte-aligned has none). The last four
#: serve the lean sampling of TPDOs (:meth:`CanopenDevice._sample`): packer None means the
#: variable is sampled by canopen's ``get_data``.
_Plan = tuple[tuple[Any, int, int, int, int, Any, Any, int, int], ...]
#: a TPDO framed by one struct (:meth:`CanopenDevice._frame_plan`): (struct, per variable
#: its application reader, per variable its (lowest, highest), payload length)
_FramePlan = tuple[struct.Struct, tuple[Callable[[], Any], ...], tuple[tuple[int, int], ...],
                   int]


def _packer(obj: Any) -> tuple[Any, int, int]:
    """How :meth:`CanopenDevice._sample` packs an integer entry: (struct, lowest, highest).

    The values it packs itself are exactly those canopen's ``encode_raw`` packs without a
    warning or an error (inside both the data type and the entry's EDS LowLimit/HighLimit);
    any other value goes to ``encode_raw``. (None, 0, 0) for any entry that is not an integer.
    """
    packer = ODVariable.STRUCT_TYPES.get(obj.data_type)
    if packer is None or obj.data_type not in INTEGER_TYPES:
        return None, 0, 0
    bits = 8 * packer.size
    lo, hi = ((-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if obj.data_type in SIGNED_TYPES
              else (0, (1 << bits) - 1))
    if obj.min is not None:
        lo = max(lo, math.ceil(obj.min))
    if obj.max is not None:
        hi = min(hi, math.floor(obj.max))
    return packer, lo, hi


#: parsed object dictionaries, pickled, by (EDS path, modification time, size, node id)
_OD_CACHE: dict[tuple[str, int, int, int], bytes] = {}


def object_dictionary(eds: str | Path, node_id: int) -> canopen.ObjectDictionary:
    """A fresh object dictionary of ``eds`` for node ``node_id``: canopen's ``import_od``.

    Why: every run builds its rig's nodes and, in process, its DUT's master node from the
    same EDS files, and canopen's parse of an EDS (configparser, then an entry per object)
    costs ~7 ms: a depth campaign sample parsed the drive's EDS 31 times. The first parse of
    a file (while its modification time and size stay the same) is kept pickled, and each
    node gets its own unpickled copy (~0.3 ms), so no two nodes share an object.
    """
    path = Path(eds)
    try:
        st = path.stat()
        key: tuple[str, int, int, int] | None = (str(path.resolve()), st.st_mtime_ns,
                                                 st.st_size, node_id)
    except OSError:
        key = None                          # canopen reports the missing file itself
    blob = _OD_CACHE.get(key) if key is not None else None
    if blob is not None:
        od: canopen.ObjectDictionary = pickle.loads(blob)
        return od
    od = canopen.import_od(str(path), node_id)
    if key is not None:
        _OD_CACHE[key] = pickle.dumps(od)
    return od


class _NoTask:
    """What ``send_periodic`` returns here: the rig schedules periodic frames itself."""

    def stop(self) -> None:
        return None

    def update(self, data: bytes) -> None:
        return None


class OutboxNetwork(canopen.Network):
    """A canopen Network without a bus: what canopen sends is collected, not transmitted.

    Frames canopen sends are collected in ``outbox`` (take them with :meth:`take`); received
    frames are fed in with ``notify``.
    """

    def __init__(self) -> None:
        super().__init__(bus=None)
        self.outbox: list[can.Message] = []

    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
        """Append the frame canopen sends to the outbox (an identifier above 0x7FF is 29-bit)."""
        self.outbox.append(can.Message(arbitration_id=can_id, data=bytes(data),
                                       is_extended_id=can_id > 0x7FF, is_remote_frame=remote))

    def send_periodic(self, can_id: int, data: bytes, period: float,
                      remote: bool = False) -> Any:
        """Start nothing (the rig schedules periodic frames itself): a task that does nothing."""
        return _NoTask()

    def take(self) -> list[can.Message]:
        """The frames collected since the last call, in order; the outbox is emptied."""
        out, self.outbox = self.outbox, []
        return out


class CanopenDevice(Device):
    """A CANopen node from an EDS, played by the rig under its clock.

    Parameters
    ----------
    name : str
        The node's name in notes and errors.
    node_id : int
        The CANopen node id.
    eds : str or Path
        The EDS file that defines its object dictionary and PDOs.
    autostart : bool, optional
        Go operational after boot-up without waiting for an NMT start (as I/O modules with NMT
        startup 0x1F80 bit 2 do); otherwise stay pre-operational.
    """

    def __init__(self, name: str, node_id: int, eds: str | Path, *,
                 autostart: bool = True) -> None:
        self.name = name
        self.node_id = node_id
        self.network = OutboxNetwork()
        self.node = canopen.LocalNode(node_id, object_dictionary(eds, node_id))
        # the node's own callback lists (live: callbacks added later are seen), which the lean
        # PDO paths call as LocalNode.get_data/set_data do
        self._read_callbacks: list[Any] = self.node._read_callbacks
        self._write_callbacks: list[Any] = self.node._write_callbacks
        self.network.add_node(self.node)
        self.autostart = autostart
        self._booted = False
        self._sync_count = 0
        #: per event-driven TPDO (map number): when it is due next, and its event timer (ms)
        self._event_due: dict[int, float] = {}
        self._event_ms: dict[int, int] = {}
        self._heartbeat_due = 0.0
        self._pending_sync_rpdos: list[tuple[PdoMap, bytes]] = []
        #: per event-driven TPDO (map number): when it last went out (its inhibit time)
        self._tpdo_sent_s: dict[int, float] = {}
        #: per acyclic synchronous TPDO (type 0): the data it last sent
        self._tpdo_last_data: dict[int, bytes] = {}
        #: configuration writes the node refused, newest last (each a ConfigRefused)
        self.refused: list[ConfigRefused] = []
        self._config_written = False
        self._in_rpdo = False
        #: RPDO values the device refused (no SDO to abort on the PDO path): (index, sub, why)
        self.rejected: list[tuple[int, int, str]] = []
        #: per PDO map: (its variable list, its length, byte plan or None); see _byte_plan
        self._plans: dict[int, tuple[Any, int, _Plan | None]] = {}
        #: per TPDO map: (its byte plan, read callbacks then, frame plan); see _frame_plan
        self._frame_plans: dict[int, tuple[_Plan | None, int, _FramePlan | None]] = {}
        self.node.nmt.state = "PRE-OPERATIONAL"
        #: heartbeat_period_s while 0x1017 is unchanged (None: read it again)
        self._heartbeat_cache: float | None = None
        self._reload_pdos()
        od = self.node.object_dictionary
        history = 0
        if 0x1003 in od:
            history = max((sub for sub in od[0x1003].subindices if sub), default=0)
        #: the node's errors (0x1001, 0x1003); raise and clear them with raise_error/clear_error
        self.errors = ErrorState(history_length=history)
        self._emcy_pending: list[bytes] = []
        self._emcy_last_s = -math.inf
        self.node.add_read_callback(self._on_error_object_read)
        self.node.add_write_callback(self._on_error_object_write)
        self.guard = CommunicationGuard(od, lambda index, sub: int(self.read(index, sub)))
        self.node.add_write_callback(self._on_configuration_write)
        self._sync_id = self._read_sync_id()
        self._heartbeat_ms = self._read_heartbeat_ms()

    # --- object dictionary helpers -------------------------------------------------------
    def read(self, index: int, subindex: int = 0) -> Any:
        """The value the object dictionary holds now (what the DUT last wrote, say).

        Decoded straight from the node's data store (what its SDO server would answer),
        without the SDO layer: this runs in the physics loop.
        """
        obj = self.node.object_dictionary[index]
        if not isinstance(obj, canopen.objectdictionary.ODVariable):
            obj = obj[subindex]
        return obj.decode_raw(self.node.get_data(index, subindex))

    def write(self, index: int, subindex: int, value: Any) -> None:
        """Set a value from the device side (a sensor reading, a statusword)."""
        obj = self.node.object_dictionary[index]
        if not isinstance(obj, canopen.objectdictionary.ODVariable):
            obj = obj[subindex]
        self.node.data_store.setdefault(index, {})[subindex] = obj.encode_raw(value)
        if index == 0x1017:
            self._heartbeat_cache = None

    # --- errors and EMCY (CiA 301) --------------------------------------------------------
    def error_register(self) -> int:
        """Object 0x1001 now (subclasses whose application keeps its own register override)."""
        return self.errors.register

    def raise_error(self, code: int, bits: int | None = None, info: int = 0) -> None:
        """Record that error ``code`` occurred and queue its EMCY.

        0x1001 and 0x1003 are updated; the EMCY is queued once while the error stays active.

        Parameters
        ----------
        code : int
            The CiA 301 error code.
        bits : int, optional
            The error register bits to set (default: from the code's class; the generic
            bit is always set).
        info : int, optional
            Manufacturer-specific information: the upper 16 bits of its 0x1003 entry.
        """
        event = self.errors.occur(code, bits, info)
        if event is not None:
            self._emcy_pending.append(emcy_payload(event[0], self.error_register()))

    def clear_error(self, code: int) -> None:
        """Error ``code`` went away: the error-reset EMCY (0x0000) is queued."""
        if self.errors.clear(code) is not None:
            self._emcy_pending.append(emcy_payload(0, self.error_register()))

    def clear_errors(self) -> None:
        """Every active error went away (a fault reset): the error-reset EMCY is queued."""
        if self.errors.clear_all() is not None:
            self._emcy_pending.append(emcy_payload(0, self.error_register()))

    def update_errors(self) -> None:
        """Hook: raise and clear errors from the application's state before EMCYs are sent."""
        return None

    def _emcy_cob_id(self) -> int | None:
        """COB-ID of EMCY from 0x1014 (None if absent or bit 31 says 'not valid')."""
        if 0x1014 not in self.node.object_dictionary:
            return None
        value = int(self.read(0x1014))
        return None if value & 0x80000000 else value & 0x7FF

    def _emcy_inhibit_s(self) -> float:
        if 0x1015 not in self.node.object_dictionary:
            return 0.0
        return int(self.read(0x1015)) * 100e-6          # multiples of 100 µs

    def _take_emcy(self, time_s: float) -> list[can.Message]:
        """The EMCY frames due now: none in stopped (they wait), one per inhibit time."""
        self.update_errors()
        if not self._emcy_pending or self.node.nmt.state == "STOPPED":
            return []
        cob_id = self._emcy_cob_id()
        if cob_id is None:
            self._emcy_pending.clear()
            return []
        inhibit = self._emcy_inhibit_s()
        out: list[can.Message] = []
        while self._emcy_pending and time_s >= self._emcy_last_s + inhibit - 1e-9:
            out.append(can.Message(arbitration_id=cob_id, data=self._emcy_pending.pop(0),
                                   is_extended_id=False))
            self._emcy_last_s = time_s
            if inhibit > 0:
                break
        return out

    def _on_error_object_read(self, index: int, subindex: int, od: Any) -> int | None:
        if index == 0x1001:
            return self.error_register()
        if index == 0x1003:
            try:
                return self.errors.field(subindex)
            except LookupError as exc:
                raise canopen.SdoAbortedError(ABORT_NO_DATA) from exc
        return None

    def _on_error_object_write(self, index: int, subindex: int, od: Any, data: bytes) -> None:
        if index == 0x1003 and subindex == 0:
            if od.decode_raw(data) != 0:
                raise canopen.SdoAbortedError(ABORT_VALUE_RANGE)
            self.errors.clear_history()

    @property
    def operational(self) -> bool:
        """Whether the node is in the NMT state operational."""
        return bool(self.node.nmt.state == "OPERATIONAL")

    def heartbeat_period_s(self) -> float:
        """The heartbeat producer time (0x1017) in seconds; 0 when the EDS has none.

        Read through the SDO layer once and kept until 0x1017 is written (an SDO or PDO write,
        :meth:`write`, a reset's restored defaults): the rig asks at every step, and the SDO
        read cost 1 s of a 45 s profile of a depth sample.
        """
        if self._heartbeat_cache is None:
            try:
                ms = int(self.node.sdo[0x1017].raw)
            except (KeyError, canopen.SdoAbortedError):
                ms = 0
            self._heartbeat_cache = ms / 1000.0
        return self._heartbeat_cache

    def _reload_pdos(self) -> None:
        self.node.tpdo.read(from_od=False)
        self.node.rpdo.read(from_od=False)
        self._rpdo_by_id: dict[int, PdoMap] = {
            m.cob_id: m for m in self.node.rpdo.map.values() if m.enabled and m.cob_id}
        #: rpdo_ids_mapping's answers while the RPDOs stay as read here
        self._ids_mapping: dict[frozenset[int], frozenset[int]] = {}
        self._tpdos = [m for m in self.node.tpdo.map.values() if m.enabled and m.cob_id]

    def rpdo_ids_mapping(self, objects: Collection[int]) -> frozenset[int]:
        """COB-IDs of the enabled RPDOs that map any of ``objects`` (object indices).

        As the master has configured them (the EDS's defaults until it does).
        """
        wanted = frozenset(objects)
        ids = self._ids_mapping.get(wanted)
        if ids is None:          # the runner asks every control period: kept until a reload
            ids = self._ids_mapping[wanted] = frozenset(
                can_id for can_id, pdo in self._rpdo_by_id.items()
                if any(var.index in wanted for var in pdo.map))
        return ids

    # --- configuration by the master (CiA 301) -------------------------------------------
    def _on_configuration_write(self, index: int, subindex: int, od: Any, data: bytes) -> None:
        """Check an SDO write before it is stored; a refusal aborts it with its code."""
        if index == 0x1017:
            self._heartbeat_cache = None    # read again once stored (or refused)
        if self._in_rpdo:
            return                          # RPDO data: mapped objects only, no SDO to abort
        value = od.decode_raw(data)
        try:
            self.guard.check(index, subindex, value)
        except ConfigRefused as exc:
            self.refused.append(exc)
            raise
        if _is_communication(index):
            self._config_written = True

    def _com_value(self, index: int, subindex: int) -> int | None:
        """A communication parameter's value now, or None if the EDS does not declare it."""
        od = self.node.object_dictionary
        if index not in od:
            return None
        obj = od[index]
        if not isinstance(obj, canopen.objectdictionary.ODVariable) and subindex not in obj:
            return None
        return int(self.read(index, subindex))

    def _read_sync_id(self) -> int:
        value = self._com_value(0x1005, 0)
        return SYNC_ID if value is None else value & 0x7FF

    def _read_heartbeat_ms(self) -> int:
        return self._com_value(0x1017, 0) or 0

    def _event_timers_ms(self) -> dict[int, int]:
        """Event timer (ms) of every valid event-driven TPDO (type 254/255) that has one."""
        timers: dict[int, int] = {}
        for key, tpdo in self.node.tpdo.map.items():
            if tpdo in self._tpdos and (tpdo.trans_type or 0) >= 254:
                ms = self._com_value(0x1800 + key - 1, 5) or 0
                if ms > 0:
                    timers[key] = ms
        return timers

    def _inhibit_s(self, key: int) -> float:
        """A TPDO's inhibit time (0x18xx:03, multiples of 100 µs) in seconds."""
        return (self._com_value(0x1800 + key - 1, 3) or 0) * 100e-6

    def _apply_configuration(self, time_s: float) -> None:
        """What the master wrote takes effect: PDOs, SYNC COB-ID, heartbeat, event timers.

        A changed heartbeat producer time restarts the heartbeat from now; a TPDO whose event
        timer was set or changed goes out one period from now.
        """
        self._reload_pdos()
        self._sync_id = self._read_sync_id()
        heartbeat_ms = self._read_heartbeat_ms()
        if heartbeat_ms != self._heartbeat_ms:
            self._heartbeat_ms = heartbeat_ms
            if self._booted:
                self._heartbeat_due = (time_s + heartbeat_ms / 1000.0 if heartbeat_ms > 0
                                       else math.inf)
        timers = self._event_timers_ms()
        for key in list(self._event_due):
            if key not in timers:
                del self._event_due[key]
        for key, ms in timers.items():
            if self._event_ms.get(key) != ms or key not in self._event_due:
                self._event_due[key] = time_s + ms / 1000.0
        self._event_ms = timers
        self.configured(time_s)

    def configured(self, time_s: float) -> None:
        """Hook: the master's configuration changed (or a reset restored the EDS defaults)."""
        return None

    def _restore_communication_defaults(self, time_s: float) -> None:
        """NMT reset: the communication objects (0x1000-0x1FFF) go back to their EDS values."""
        store = self.node.data_store
        for index in [i for i in store if 0x1000 <= i <= 0x1FFF]:
            del store[index]
        self._heartbeat_cache = None
        self._tpdo_sent_s.clear()
        self._tpdo_last_data.clear()
        self._apply_configuration(time_s)

    # --- Device ----------------------------------------------------------------------------
    def next_due(self, time_s: float) -> float:
        """The earliest of the next heartbeat, event-timer TPDO and pending EMCY after ``time_s``.

        Before boot-up: 0 (the boot-up message goes out first).
        """
        if not self._booted:
            return 0.0
        candidates = [math.inf]
        period = self.heartbeat_period_s()
        if period > 0:
            while self._heartbeat_due <= time_s + 1e-9:
                self._heartbeat_due += period
            candidates.append(self._heartbeat_due)
        for key, due in self._event_due.items():
            if due <= time_s + 1e-9:
                # not sent yet (silent, or asked before emit): the next tick of its timer; the
                # schedule itself moves only when the TPDO goes out (emit)
                period = self._event_period(key)
                due += (math.floor((time_s + 1e-9 - due) / period) + 1) * period
            candidates.append(due)
        if self._emcy_pending and self.node.nmt.state != "STOPPED":   # stopped: they wait
            candidates.append(max(self._emcy_last_s + self._emcy_inhibit_s(), time_s + 1e-6))
        return min(candidates)

    def _event_period(self, key: int) -> float:
        return max(1, self._event_ms.get(key, 0)) / 1000.0

    def emit(self, time_s: float) -> list[can.Message]:
        """The frames due at ``time_s``: boot-up first, then EMCYs, the heartbeat and event TPDOs.

        Event-timer TPDOs go out only in operational; a silent node sends nothing.
        """
        if self.silent:
            return []
        out: list[can.Message] = []
        if not self._booted:
            self._booted = True
            out.append(can.Message(arbitration_id=0x700 + self.node_id, data=b"\x00",
                                   is_extended_id=False))          # boot-up
            if self.autostart:
                self._enter("OPERATIONAL")
            period = self.heartbeat_period_s()
            self._heartbeat_due = period if period > 0 else math.inf
            return out
        out.extend(self._take_emcy(time_s))
        if self._heartbeat_due <= time_s + 1e-9:
            out.append(can.Message(arbitration_id=0x700 + self.node_id,
                                   data=bytes([NMT_STATES.get(self.node.nmt.state, 0x7F)]),
                                   is_extended_id=False))
        if self.operational:
            for key, due in self._event_due.items():
                if due <= time_s + 1e-9:
                    inhibit_end = self._tpdo_sent_s.get(key, -math.inf) + self._inhibit_s(key)
                    if time_s + 1e-9 < inhibit_end:
                        self._event_due[key] = inhibit_end       # within its inhibit time
                        continue
                    out.append(self._tpdo_frame(self.node.tpdo.map[key]))
                    self._tpdo_sent_s[key] = time_s
                    self._event_due[key] = time_s + self._event_period(key)
        return out

    def accepts(self, msg: can.Message) -> bool:
        """Whether ``msg`` is for this node: NMT (0x000), SYNC, its SDO requests or its RPDOs."""
        can_id = msg.arbitration_id
        return (not msg.is_extended_id and (can_id in (0x000, self._sync_id,
                                                       0x600 + self.node_id)
                                            or can_id in self._rpdo_by_id))

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        """Handle a frame for this node under the NMT state rules; return the replies.

        SYNC (on the COB-ID in 0x1005) sends the synchronous TPDOs (operational only); RPDOs are
        stored, synchronous ones (types 0-240) at the next SYNC; NMT commands change the state (a
        reset sends the boot-up message); SDO requests are answered by canopen's SDO server,
        except in stopped, and a configuration the master wrote takes effect once stored.
        """
        if self.silent:
            return []
        can_id, data = msg.arbitration_id, bytes(msg.data)
        if can_id == self._sync_id:
            return self._on_sync(time_s) if self.operational else []
        if can_id in self._rpdo_by_id:
            if self.operational:
                rpdo = self._rpdo_by_id[can_id]
                if not self._rpdo_length_ok(rpdo, data):
                    return []
                trans_type = rpdo.trans_type
                if trans_type is not None and trans_type <= 240:
                    # synchronous RPDO: actuated at the next SYNC (CiA 301)
                    self._pending_sync_rpdos.append((rpdo, data))
                else:
                    self._store_rpdo(rpdo, data)
            return []
        if can_id != 0x000 and self.node.nmt.state == "STOPPED":
            return []                 # stopped: only NMT commands are answered (CiA 301)
        before = self.node.nmt.state
        self.network.notify(can_id, data, time_s)
        if can_id == 0x000 and self.node.nmt.state == "INITIALISING":
            return self._reset(time_s)
        if can_id == 0x000 and self.node.nmt.state != before:
            self._enter(self.node.nmt.state)
        if self._config_written:
            self._config_written = False
            self._apply_configuration(time_s)
        return self.network.take() + self._take_emcy(time_s)

    def _reset(self, time_s: float) -> list[can.Message]:
        """NMT reset node or reset communication: the boot-up message, then pre-operational.

        With autostart the node goes operational; the heartbeat restarts from now. The
        communication objects take their EDS values again (CiA 301: the master configures the
        node anew after a reset); the application (a drive's state machine) is not reset.
        """
        self.network.take()
        self._pending_sync_rpdos.clear()
        self._sync_count = 0
        self._restore_communication_defaults(time_s)
        self._enter("OPERATIONAL" if self.autostart else "PRE-OPERATIONAL")
        period = self.heartbeat_period_s()
        self._heartbeat_due = time_s + period if period > 0 else math.inf
        return [can.Message(arbitration_id=0x700 + self.node_id, data=b"\x00",
                            is_extended_id=False)]

    def enter_state(self, state: str) -> None:
        """Change the NMT state from the application (CiA 301 error behaviour, say)."""
        if state != self.node.nmt.state:
            self._enter(state)

    def _enter(self, state: str) -> None:
        self.node.nmt.state = state
        if state != "OPERATIONAL":
            self._pending_sync_rpdos.clear()      # no PDO is processed outside operational
        if state == "OPERATIONAL":
            self._reload_pdos()
            self._event_ms = self._event_timers_ms()
            self._event_due = dict.fromkeys(self._event_ms, 0.0)

    def _on_sync(self, time_s: float) -> list[can.Message]:
        self._sync_count += 1
        pending, self._pending_sync_rpdos = self._pending_sync_rpdos, []
        for rpdo, data in pending:
            self._store_rpdo(rpdo, data)
        self.before_sync()
        out = self._take_emcy(time_s) + self.events()
        for tpdo in self._tpdos:
            n = tpdo.trans_type or 0
            if 1 <= n <= 240 and self._sync_count % n == 0:
                out.append(self._tpdo_frame(tpdo))
            elif n == 0:
                # synchronous acyclic: at the SYNC after its data changed (the first SYNC too)
                frame = self._tpdo_frame(tpdo)
                key = tpdo.com_record.od.index
                if self._tpdo_last_data.get(key) != bytes(frame.data):
                    self._tpdo_last_data[key] = bytes(frame.data)
                    out.append(frame)
        return out

    def events(self) -> list[can.Message]:
        """Hook: event frames to send at SYNC ahead of the TPDOs (after the EMCYs)."""
        return []

    def before_sync(self) -> None:
        """Hook: refresh the object dictionary from the physics before TPDOs are sampled."""
        return None

    def app_reader(self, index: int, subindex: int) -> Callable[[], Any] | None:
        """Hook: a function giving what the application's read callback answers now, or None.

        For entry ``index:subindex``; None: the callbacks are asked. A TPDO all of whose
        variables have one is framed by :meth:`_frame_plan`'s single ``struct`` call. The
        node's own error objects (0x1001, 0x1003) are never read through it.
        """
        return None

    def _tpdo_frame(self, tpdo: PdoMap) -> can.Message:
        fast = self._frame_plan(tpdo)
        if fast is not None:
            packer, readers, ranges, size = fast
            values = [read() for read in readers]
            for value, (lo, hi) in zip(values, ranges, strict=True):
                if type(value) is not int or not lo <= value <= hi:
                    break                   # canopen's rules for this value: the path below
            else:
                payload = packer.pack(*values)
                tpdo.data[:size] = payload
                return can.Message(arbitration_id=tpdo.cob_id, data=payload,
                                   is_extended_id=False)
        plan = self._byte_plan(tpdo)
        if plan is None:
            for var in tpdo.map:
                var.set_data(self.node.get_data(var.index, var.subindex))
        else:
            # canopen's own byte-aligned branch of PdoVariable.set_data, without its per-variable
            # debug formatting: the same bytes land in the same map buffer
            data, get, sample = tpdo.data, self.node.get_data, self._sample
            for _, index, subindex, start, _, obj, packer, lo, hi in plan:
                value = (get(index, subindex) if packer is None
                         else sample(obj, index, subindex, packer, lo, hi))
                data[start:start + len(value)] = value
            tpdo.update()
        return can.Message(arbitration_id=tpdo.cob_id, data=bytes(tpdo.data),
                           is_extended_id=False)

    def _sample(self, obj: Any, index: int, subindex: int, packer: Any, lo: int,
                hi: int) -> bytes:
        """What ``LocalNode.get_data(index, subindex)`` returns, for a TPDO's integer entry.

        Why not canopen's own: a depth sample frames ~230,000 TPDO variables, and
        ``get_data`` spent 4.4 s of a 45 s profile of one sample (finding the entry again, then
        ``encode_raw``'s type and range checks, for every variable at every SYNC); this is the
        same lookup in the same order (read callbacks, then the data store, then canopen for
        the EDS value) with the entry found once per mapping and an in-range integer packed by
        the entry's own struct. Anything else (a value out of its range, not an int, no stored
        data) goes to canopen. :meth:`_byte_plan` checks it against ``get_data`` for every
        variable when it builds a plan and leaves any that disagree to canopen.
        """
        for callback in self._read_callbacks:
            result = callback(index=index, subindex=subindex, od=obj)
            if result is not None:
                if type(result) is int and lo <= result <= hi:
                    return bytes(packer.pack(result))
                return bytes(obj.encode_raw(result))
        try:
            return bytes(self.node.data_store[index][subindex])
        except KeyError:
            return bytes(self.node.get_data(index, subindex))

    def _rpdo_length_ok(self, rpdo: PdoMap, data: bytes) -> bool:
        """Whether to process an RPDO of this length (CiA 301), raising or ending its errors.

        Shorter than its mapping: not processed, EMCY 0x8210; longer: processed by its first
        bytes, EMCY 0x8220; the right length ends either error.
        """
        need = (rpdo.length + 7) // 8
        if len(data) < need:
            self.raise_error(PDO_LENGTH_ERROR, ErrorRegister.COMMUNICATION)
            return False
        if len(data) > need:
            self.raise_error(PDO_LENGTH_EXCEEDED, ErrorRegister.COMMUNICATION)
        elif self.errors.active:
            self.clear_error(PDO_LENGTH_ERROR)
            self.clear_error(PDO_LENGTH_EXCEEDED)
        return True

    def _store_rpdo(self, rpdo: PdoMap, data: bytes) -> None:
        size = len(rpdo.data)
        rpdo.data = bytearray(data[:size].ljust(size, b"\x00"))
        plan = self._byte_plan(rpdo)
        self._in_rpdo = True
        try:
            if plan is None:
                for var in rpdo.map:
                    bits = var.get_data()
                    try:
                        self.node.set_data(var.index, var.subindex, bits)
                    except (canopen.SdoAbortedError, ValueError) as exc:
                        self.rejected.append((var.index, var.subindex, str(exc)))
                return
            store, callbacks = self.node.data_store, self._write_callbacks
            for _, index, subindex, start, stop, obj, _, _, _ in plan:
                # LocalNode.set_data without finding the entry again (found once per mapping)
                # and without its length check, which a byte plan's slice (the entry's own
                # size) always passes; the value is canopen's byte-aligned PdoVariable.get_data,
                # a slice of the map buffer
                value = rpdo.data[start:stop]
                try:
                    for callback in callbacks:
                        callback(index=index, subindex=subindex, od=obj, data=value)
                except (canopen.SdoAbortedError, ValueError) as exc:
                    self.rejected.append((index, subindex, str(exc)))
                    continue
                store.setdefault(index, {})[subindex] = bytes(value)
        finally:
            self._in_rpdo = False

    def _byte_plan(self, pdo: PdoMap) -> _Plan | None:
        """The byte plan of a PDO map, or None if any variable is not whole bytes at a whole byte.

        The plan is (variable, index, subindex, first byte, end byte, entry, packer, lowest,
        highest) of every mapped variable (None: canopen's bit-level path). Kept per map and
        rebuilt when canopen rebuilds the map's variable list (a new list on every ``read``) or
        adds to it. A variable whose lean sample (:meth:`_sample`) differs from canopen's
        ``get_data`` now, or that canopen cannot read now, is sampled by ``get_data`` (packer
        None).
        """
        variables = pdo.map
        cached = self._plans.get(id(pdo))
        if cached is not None and cached[0] is variables and cached[1] == len(variables):
            return cached[2]
        plan: _Plan | None = None
        if not any(var.offset is None or var.offset % 8 or var.length % 8 for var in variables):
            plan = tuple((var, var.index, var.subindex, var.offset // 8,
                          var.offset // 8 + len(var.od) // 8, var.od,
                          *self._checked_packer(var.od, var.index, var.subindex))
                         for var in variables)
        self._plans[id(pdo)] = (variables, len(variables), plan)
        return plan

    def _frame_plan(self, pdo: PdoMap) -> _FramePlan | None:
        """A TPDO's payload as one ``struct`` of the application's values, or None.

        Why: a depth campaign sample frames ~230,000 TPDOs, and asking the read callbacks
        variable by variable (``_sample``: the node's error objects first, then the drive's
        callback, its object lookup and its getter) was ~1 s of CPU of its ~15 s. This plan
        reads each variable with the function :meth:`app_reader` gives and packs the frame
        with one ``struct``. It exists when the map has a byte plan whose variables are all
        packed by :meth:`_sample` itself (in-range integers), lie end to end from byte 0 and
        each have an application reader whose value now is what the callbacks answer (checked
        when the plan is built; the byte plan has checked the bytes against canopen's
        ``get_data``). A value that is not an in-range int at run time is framed by the byte
        plan's path (canopen's rules). Kept as the byte plan is, and rebuilt when a read
        callback is added.
        """
        plan = self._byte_plan(pdo)
        key = id(pdo)
        cached = self._frame_plans.get(key)
        callbacks = len(self._read_callbacks)
        if cached is not None and cached[0] is plan and cached[1] == callbacks:
            return cached[2]
        fast: _FramePlan | None = None
        if plan is not None and all(step[6] is not None for step in plan):
            readers: list[Callable[[], Any]] = []
            fmt, end = "<", 0
            for _, index, subindex, start, stop, obj, packer, _, _ in plan:
                read = (None if index in (0x1001, 0x1003) or start != end
                        else self.app_reader(index, subindex))
                if read is None or not self._reader_agrees(read, obj, index, subindex):
                    break
                readers.append(read)
                fmt += packer.format.lstrip("<>=!@")
                end = stop
            else:
                if end == len(pdo.data):
                    fast = (struct.Struct(fmt), tuple(readers),
                            tuple((step[7], step[8]) for step in plan), end)
        self._frame_plans[key] = (plan, callbacks, fast)
        return fast

    def _reader_agrees(self, read: Callable[[], Any], obj: Any, index: int,
                       subindex: int) -> bool:
        """Whether an application reader gives what the read callbacks answer now."""
        try:
            value = read()
            for callback in self._read_callbacks:
                answer = callback(index=index, subindex=subindex, od=obj)
                if answer is not None:
                    return type(answer) is type(value) and answer == value
        except (canopen.SdoAbortedError, ValueError, KeyError, LookupError):
            return False
        return False                        # no callback answers: the data store does

    def _checked_packer(self, obj: Any, index: int, subindex: int) -> tuple[Any, int, int]:
        """:func:`_packer` of an entry if :meth:`_sample` gives canopen's bytes for it now."""
        packer, lo, hi = _packer(obj)
        if packer is None:
            return None, 0, 0
        try:
            same = (self._sample(obj, index, subindex, packer, lo, hi)
                    == bytes(self.node.get_data(index, subindex)))
        except (canopen.SdoAbortedError, ValueError, KeyError):
            same = False
        return (packer, lo, hi) if same else (None, 0, 0)
