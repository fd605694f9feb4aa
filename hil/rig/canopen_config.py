"""What a CANopen master may write to a node's communication objects (CiA 301), and why not.

A master configures its slaves at boot by SDO: PDO communication parameters (RPDO 0x1400-0x15FF,
TPDO 0x1800-0x19FF), PDO mappings (0x1600-0x17FF, 0x1A00-0x1BFF), the SYNC COB-ID 0x1005, the
EMCY COB-ID 0x1014, the consumer heartbeat times 0x1016. :class:`CommunicationGuard` checks
each such write against the node's object dictionary (its EDS) and the values it holds now,
before the write is stored, and refuses what CiA 301 or the EDS does not allow with the SDO
abort code a real node sends (:class:`SdoAbort`). It is pure logic: the rig's
:class:`~hil.rig.canopen_device.CanopenDevice` runs it from the ``LocalNode``'s write callback,
so canopen's SDO server sends the abort.

The rules (the re-mapping sequence of CiA 301 is: invalidate the PDO by setting bit 31 of its
COB-ID, write 0 to sub-index 0 of its mapping, write the entries, write their count, clear
bit 31):

* COB-IDs (PDOs, SYNC, EMCY) are 11-bit: bit 29 (29-bit frame) or any of bits 11-28 set is out
  of range (0x06090030), as is a restricted CAN-ID of CiA 301 table 3 (0x000-0x07F,
  0x101-0x180, 0x581-0x5FF, 0x601-0x67F, 0x6E0-0x6FF, 0x701-0x7FF). The CAN-ID of a valid PDO
  or EMCY cannot change while it stays valid (0x06090030); a PDO made valid on a CAN-ID that one
  of the node's other valid PDOs, its EMCY or SYNC already uses is refused (0x06040043).
* Transmission types: 0-240, 254, 255; the RTR-only TPDO types 252/253 and the reserved values
  are out of range (0x06090030). A TPDO's inhibit time cannot change while the PDO is valid
  (0x06090030). Event timers may change at any time.
* Mapping: a write to a mapping while its PDO is valid, or to an entry while sub-index 0 is not
  0, is refused because of the present state (0x08000022). An entry must name an object that
  exists (0x06020000), may be mapped (EDS ``PDOMapping=1``) in that direction (an RPDO writes,
  so the object must be writable; a TPDO reads) and is not a dummy (both EDS declare no dummy
  usage) (0x06040041), with its full bit length (0x06040043: no partial mapping). Sub-index 0
  beyond the declared entries or a total beyond 64 bits is refused (0x06040042).
* SYNC COB-ID: the node is a SYNC consumer only; bit 30 (generate SYNC) is refused (0x06090030).
* Consumer heartbeat (0x1016): bits 24-31 are reserved (0x06090030); a node id beyond 127 is out
  of range (0x06090030); two entries with a time for the same node are refused (0x06040043).
* Any object with ``LowLimit``/``HighLimit`` in the EDS: above is 0x06090031, below 0x06090032.
* A sub-index an array does not declare: 0x06090011 (canopen's ``LocalNode`` would make one up).

Example
-------
>>> import canopen
>>> from plant_emulators.sowing_depth.frames import EDS_PATH
>>> node = canopen.LocalNode(2, str(EDS_PATH))
>>> guard = CommunicationGuard(node.object_dictionary, lambda i, s: node.sdo[i][s].raw)
>>> try:
...     guard.check(0x1600, 1, 0x60410010)        # statusword into RPDO1 while RPDO1 is valid
... except ConfigRefused as exc:
...     hex(exc.code)
'0x8000022'
"""

from __future__ import annotations

import enum
from collections.abc import Callable

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable

__all__ = ["CommunicationGuard", "ConfigRefused", "SdoAbort", "is_restricted_can_id"]

#: bit 31 of a PDO or EMCY COB-ID: the object does not exist (is not valid)
NOT_VALID = 0x80000000
#: bit 30 of the SYNC COB-ID: the node generates SYNC
SYNC_PRODUCER = 0x40000000
#: bit 29 of a COB-ID: 29-bit CAN identifier
EXTENDED_FRAME = 0x20000000
_EXTENDED_ID_BITS = 0x1FFFF800
_MAX_PDO_BITS = 64

#: CAN-IDs a PDO, SYNC or EMCY may not use (CiA 301 table 3), as inclusive ranges
_RESTRICTED = ((0x000, 0x07F), (0x101, 0x180), (0x581, 0x5FF), (0x601, 0x67F), (0x6E0, 0x6FF),
               (0x701, 0x7FF))


class SdoAbort(enum.IntEnum):
    """The SDO abort codes (CiA 301 table 22) a node refuses configuration with."""

    READ_ONLY = 0x06010002
    NO_OBJECT = 0x06020000
    NOT_MAPPABLE = 0x06040041
    PDO_LENGTH = 0x06040042
    PARAMETER_INCOMPATIBLE = 0x06040043
    NO_SUB_INDEX = 0x06090011
    VALUE_RANGE = 0x06090030
    VALUE_TOO_HIGH = 0x06090031
    VALUE_TOO_LOW = 0x06090032
    DEVICE_STATE = 0x08000022


class ConfigRefused(canopen.SdoAbortedError):
    """A configuration write the node refuses: ``code`` is its SDO abort code, ``reason`` why.

    A ``canopen.SdoAbortedError``, so raised from a ``LocalNode`` write callback it makes
    canopen's SDO server send the abort.
    """

    def __init__(self, code: SdoAbort, index: int, subindex: int, reason: str) -> None:
        super().__init__(int(code))
        self.index = index
        self.subindex = subindex
        self.reason = reason

    def __str__(self) -> str:
        return (f"0x{self.index:04X}:{self.subindex:02X}: {self.reason} "
                f"(SDO abort 0x{self.code:08X})")


def is_restricted_can_id(can_id: int) -> bool:
    """Whether an 11-bit CAN-ID is one CiA 301 reserves (NMT, SDO, heartbeat, LSS, ...).

    >>> is_restricted_can_id(0x182), is_restricted_can_id(0x581), is_restricted_can_id(0x080)
    (False, True, False)
    """
    return any(lo <= can_id <= hi for lo, hi in _RESTRICTED)


def _is_rpdo_com(index: int) -> bool:
    return 0x1400 <= index <= 0x15FF


def _is_tpdo_com(index: int) -> bool:
    return 0x1800 <= index <= 0x19FF


def _is_rpdo_map(index: int) -> bool:
    return 0x1600 <= index <= 0x17FF


def _is_tpdo_map(index: int) -> bool:
    return 0x1A00 <= index <= 0x1BFF


class CommunicationGuard:
    """Checks a master's writes to a node's communication objects before they are stored.

    Parameters
    ----------
    od : canopen.ObjectDictionary
        The node's object dictionary (from its EDS).
    get : callable
        ``get(index, subindex) -> int``: the value the node holds now.
    """

    def __init__(self, od: canopen.ObjectDictionary, get: Callable[[int, int], int]) -> None:
        self.od = od
        self.get = get

    # --- entry point -------------------------------------------------------------------------
    def check(self, index: int, subindex: int, value: int) -> None:
        """Refuse ``value`` for ``index:subindex`` if the node may not take it.

        Raises
        ------
        ConfigRefused
            With the SDO abort code of the first rule the write breaks (see the module).
        """
        obj = self.od.get(index)
        if isinstance(obj, ODArray) and subindex not in obj.subindices:
            # canopen's LocalNode would make one up from the array's first entry
            raise self._refuse(SdoAbort.NO_SUB_INDEX, index, subindex,
                               f"{obj.name} has no sub-index {subindex}")
        if _is_rpdo_com(index) or _is_tpdo_com(index):
            self._check_pdo_communication(index, subindex, value)
        elif _is_rpdo_map(index) or _is_tpdo_map(index):
            self._check_mapping(index, subindex, value)
        elif index == 0x1005:
            self._check_sync_cob_id(value)
        elif index == 0x1014:
            self._check_emcy_cob_id(value)
        elif index == 0x1016 and subindex > 0:
            self._check_consumer_heartbeat(subindex, value)
        self._check_limits(index, subindex, value)

    # --- helpers --------------------------------------------------------------------------------
    def _variable(self, index: int, subindex: int) -> ODVariable | None:
        if index not in self.od:
            return None
        obj = self.od[index]
        if isinstance(obj, (ODRecord, ODArray)):
            # the declared sub-indices: an ODArray makes up a variable for any sub-index
            return obj.subindices.get(subindex)
        return obj if subindex == 0 else None

    def _has(self, index: int, subindex: int) -> bool:
        return self._variable(index, subindex) is not None

    def _refuse(self, code: SdoAbort, index: int, subindex: int, reason: str) -> ConfigRefused:
        return ConfigRefused(code, index, subindex, reason)

    def _check_11_bit(self, index: int, subindex: int, value: int) -> None:
        if value & EXTENDED_FRAME:
            raise self._refuse(SdoAbort.VALUE_RANGE, index, subindex,
                               "29-bit CAN identifiers (bit 29) are not supported")
        if value & _EXTENDED_ID_BITS:
            raise self._refuse(SdoAbort.VALUE_RANGE, index, subindex,
                               f"bits 11-28 of 0x{value:08X} must be 0 for an 11-bit CAN-ID")

    def _used_can_ids(self, skip: int) -> dict[int, str]:
        """CAN-ID → its user: the node's valid PDOs (but the one at ``skip``), EMCY and SYNC."""
        used: dict[int, str] = {}
        for base, kind in ((0x1400, "RPDO"), (0x1800, "TPDO")):
            for number in range(512):
                index = base + number
                if index == skip or index not in self.od:
                    continue
                cob = int(self.get(index, 1))
                if not cob & NOT_VALID:
                    used[cob & 0x7FF] = f"{kind}{number + 1} (0x{index:04X})"
        if 0x1014 in self.od and not int(self.get(0x1014, 0)) & NOT_VALID:
            used[int(self.get(0x1014, 0)) & 0x7FF] = "EMCY (0x1014)"
        if 0x1005 in self.od:
            used[int(self.get(0x1005, 0)) & 0x7FF] = "SYNC (0x1005)"
        return used

    # --- PDO communication parameters --------------------------------------------------------
    def _check_pdo_communication(self, index: int, subindex: int, value: int) -> None:
        name = f"{'RPDO' if _is_rpdo_com(index) else 'TPDO'}{(index & 0x1FF) + 1}"
        valid_now = not int(self.get(index, 1)) & NOT_VALID
        if subindex == 1:
            self._check_11_bit(index, 1, value)
            valid_new = not value & NOT_VALID
            current = int(self.get(index, 1))
            if valid_now and valid_new and (value & 0x3FFFFFFF) != (current & 0x3FFFFFFF):
                raise self._refuse(
                    SdoAbort.VALUE_RANGE, index, 1,
                    f"{name} is valid: its CAN-ID 0x{current & 0x7FF:03X} cannot change to "
                    f"0x{value & 0x7FF:03X} (set bit 31 first)")
            if valid_new:
                can_id = value & 0x7FF
                if is_restricted_can_id(can_id):
                    raise self._refuse(SdoAbort.VALUE_RANGE, index, 1,
                                       f"CAN-ID 0x{can_id:03X} is restricted by CiA 301")
                owner = self._used_can_ids(skip=index).get(can_id)
                if owner is not None:
                    raise self._refuse(SdoAbort.PARAMETER_INCOMPATIBLE, index, 1,
                                       f"CAN-ID 0x{can_id:03X} is already used by {owner}")
        elif subindex == 2:
            allowed = value <= 240 or value >= 254
            if not allowed:
                kind = ("RTR-only transmission (252/253) is not supported"
                        if value in (252, 253) and _is_tpdo_com(index) else "is reserved")
                raise self._refuse(SdoAbort.VALUE_RANGE, index, 2,
                                   f"{name} transmission type {value}: {kind}")
        elif (subindex == 3 and _is_tpdo_com(index) and valid_now
              and value != int(self.get(index, 3))):
            raise self._refuse(SdoAbort.VALUE_RANGE, index, 3,
                               f"{name} is valid: its inhibit time cannot change "
                               "(set bit 31 of sub-index 1 first)")

    # --- PDO mapping --------------------------------------------------------------------------
    def _check_mapping(self, index: int, subindex: int, value: int) -> None:
        rx = _is_rpdo_map(index)
        com = index - 0x200
        name = f"{'RPDO' if rx else 'TPDO'}{(index & 0x1FF) + 1}"
        if com in self.od and not int(self.get(com, 1)) & NOT_VALID:
            raise self._refuse(SdoAbort.DEVICE_STATE, index, subindex,
                               f"{name} is valid: set bit 31 of 0x{com:04X}:01 before mapping")
        if subindex == 0:
            capacity = max((sub for sub in self.od[index].subindices if sub), default=0)
            if value > capacity:
                raise self._refuse(SdoAbort.PDO_LENGTH, index, 0,
                                   f"{name} has {capacity} mapping entries, not {value}")
            bits = 0
            for sub in range(1, value + 1):
                entry = int(self.get(index, sub))
                self._check_entry(index, sub, entry, rx)
                bits += entry & 0xFF
            if bits > _MAX_PDO_BITS:
                raise self._refuse(SdoAbort.PDO_LENGTH, index, 0,
                                   f"{name} would carry {bits} bits, more than 64")
            return
        if int(self.get(index, 0)) != 0:
            raise self._refuse(SdoAbort.DEVICE_STATE, index, subindex,
                               f"{name}'s mapping is active: write 0 to 0x{index:04X}:00 first")
        if value != 0:
            self._check_entry(index, subindex, value, rx)

    def _check_entry(self, index: int, subindex: int, entry: int, rx: bool) -> None:
        target, target_sub, bits = entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF
        where = f"0x{target:04X}:{target_sub:02X}"
        if target == 0:
            raise self._refuse(SdoAbort.NOT_MAPPABLE, index, subindex,
                               "an empty entry (0x00000000) within the mapped count")
        if target <= 0x0007:
            raise self._refuse(SdoAbort.NOT_MAPPABLE, index, subindex,
                               f"dummy mapping of data type 0x{target:04X} is not supported")
        var = self._variable(target, target_sub)
        if var is None:
            raise self._refuse(SdoAbort.NO_OBJECT, index, subindex,
                               f"mapped object {where} does not exist")
        if not var.pdo_mappable:
            raise self._refuse(SdoAbort.NOT_MAPPABLE, index, subindex,
                               f"{where} {var.name} cannot be mapped (EDS PDOMapping=0)")
        if rx and not var.writable:
            raise self._refuse(SdoAbort.NOT_MAPPABLE, index, subindex,
                               f"{where} {var.name} is {var.access_type}: an RPDO cannot write it")
        if not rx and not var.readable:
            raise self._refuse(SdoAbort.NOT_MAPPABLE, index, subindex,
                               f"{where} {var.name} is {var.access_type}: a TPDO cannot read it")
        if bits != len(var):
            raise self._refuse(SdoAbort.PARAMETER_INCOMPATIBLE, index, subindex,
                               f"{where} {var.name} is {len(var)} bits, not {bits}")

    # --- SYNC, EMCY, heartbeat consumer ------------------------------------------------------
    def _check_sync_cob_id(self, value: int) -> None:
        if value & SYNC_PRODUCER:
            raise self._refuse(SdoAbort.VALUE_RANGE, 0x1005, 0,
                               "the node is a SYNC consumer; it cannot generate SYNC (bit 30)")
        self._check_11_bit(0x1005, 0, value)
        if is_restricted_can_id(value & 0x7FF):
            raise self._refuse(SdoAbort.VALUE_RANGE, 0x1005, 0,
                               f"CAN-ID 0x{value & 0x7FF:03X} is restricted by CiA 301")

    def _check_emcy_cob_id(self, value: int) -> None:
        self._check_11_bit(0x1014, 0, value)
        current = int(self.get(0x1014, 0))
        if (not current & NOT_VALID and not value & NOT_VALID
                and (value & 0x3FFFFFFF) != (current & 0x3FFFFFFF)):
            raise self._refuse(SdoAbort.VALUE_RANGE, 0x1014, 0,
                               "EMCY is valid: its CAN-ID cannot change (set bit 31 first)")
        if not value & NOT_VALID and is_restricted_can_id(value & 0x7FF):
            raise self._refuse(SdoAbort.VALUE_RANGE, 0x1014, 0,
                               f"CAN-ID 0x{value & 0x7FF:03X} is restricted by CiA 301")

    def _check_consumer_heartbeat(self, subindex: int, value: int) -> None:
        if value & 0xFF000000:
            raise self._refuse(SdoAbort.VALUE_RANGE, 0x1016, subindex,
                               "bits 24-31 of a consumer heartbeat time are reserved")
        node, time_ms = (value >> 16) & 0xFF, value & 0xFFFF
        if node > 127:
            raise self._refuse(SdoAbort.VALUE_RANGE, 0x1016, subindex,
                               f"node id {node} is beyond 127")
        if node == 0 or time_ms == 0:
            return
        for sub in self.od[0x1016].subindices:
            if sub in (0, subindex):
                continue
            other = int(self.get(0x1016, sub))
            if (other >> 16) & 0xFF == node and other & 0xFFFF:
                raise self._refuse(SdoAbort.PARAMETER_INCOMPATIBLE, 0x1016, subindex,
                                   f"node {node} is already monitored by 0x1016:{sub:02X}")

    def _check_limits(self, index: int, subindex: int, value: int) -> None:
        var = self._variable(index, subindex)
        if var is None or not isinstance(value, int):
            return
        if var.max is not None and value > var.max:
            raise self._refuse(SdoAbort.VALUE_TOO_HIGH, index, subindex,
                               f"{var.name}: {value} is above the EDS HighLimit {var.max}")
        if var.min is not None and value < var.min:
            raise self._refuse(SdoAbort.VALUE_TOO_LOW, index, subindex,
                               f"{var.name}: {value} is below the EDS LowLimit {var.min}")
