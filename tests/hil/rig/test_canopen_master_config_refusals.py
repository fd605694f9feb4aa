"""What the rig's CANopen nodes refuse from a master, each with its SDO abort code (CiA 301).

canopen's ``RemoteNode`` writes by SDO to the servo drive (CiA 402) and the analog output module
(CiA 401) in lockstep (:class:`~.test_canopen_master_config.Loopback`); each refused write
aborts with the code CiA 301 gives, leaves the node's value as it was, and is kept with its
reason in ``device.refused``.
"""

from __future__ import annotations

import struct

import canopen
import numpy as np
import pytest
from canopen.objectdictionary import ODRecord, ODVariable, datatypes

from hil.rig.canopen_config import CommunicationGuard, ConfigRefused, SdoAbort
from plant_emulators.fertilizer.analog_output import AnalogOutputChannel
from plant_emulators.fertilizer.config import load_rig_config as load_fertilizer_config
from plant_emulators.fertilizer.devices import AnalogOutputModule

from .test_canopen_master_config import Loopback, drive_loop

A = SdoAbort
#: invalidate RPDO1 / TPDO1 / TPDO2 and clear a mapping's count: the CiA 301 re-mapping start
RPDO1_OFF = ((0x1400, 1, 0x80000202),)
RPDO1_UNMAPPED = (*RPDO1_OFF, (0x1600, 0, 0))
TPDO2_OFF = ((0x1801, 1, 0x80000282),)


def sdo_write(master: canopen.RemoteNode, index: int, subindex: int, value: int) -> None:
    """Download ``value`` encoded as the master's EDS types it (32 bits for unknown objects)."""
    try:
        obj = master.object_dictionary[index]
        var = obj if isinstance(obj, canopen.objectdictionary.ODVariable) else obj[subindex]
        data = var.encode_raw(value)
    except KeyError:
        data = struct.pack("<I", value)
    master.sdo.download(index, subindex, data)


def sdo_read(master: canopen.RemoteNode, index: int, subindex: int) -> int:
    obj = master.object_dictionary[index]
    var = obj if isinstance(obj, canopen.objectdictionary.ODVariable) else obj[subindex]
    return int(var.decode_raw(master.sdo.upload(index, subindex)))


DRIVE_CASES = [
    # (what, writes that succeed first, the refused write, its abort code)
    ("no RPDO4 in the EDS", (), (0x1403, 1, 0x80000502), A.NO_OBJECT),
    ("highest sub-index is const", (), (0x1400, 0, 3), A.READ_ONLY),
    ("TPDO sub-index 4 is reserved", (), (0x1800, 4, 0), A.NO_SUB_INDEX),
    ("mapping a valid RPDO", (), (0x1600, 1, 0x60400010), A.DEVICE_STATE),
    ("count of a valid RPDO", (), (0x1600, 0, 0), A.DEVICE_STATE),
    ("entry while the count is not 0", RPDO1_OFF, (0x1600, 1, 0x60400010), A.DEVICE_STATE),
    ("statusword is read-only: no RPDO", RPDO1_UNMAPPED, (0x1600, 1, 0x60410010),
     A.NOT_MAPPABLE),
    ("following error window: PDOMapping=0", RPDO1_UNMAPPED, (0x1600, 1, 0x60650020),
     A.NOT_MAPPABLE),
    ("no object 0x7000", RPDO1_UNMAPPED, (0x1600, 1, 0x70000010), A.NO_OBJECT),
    ("no sub-index 0x607D:05", RPDO1_UNMAPPED, (0x1600, 1, 0x607D0520), A.NO_OBJECT),
    ("dummy entries are not supported", RPDO1_UNMAPPED, (0x1600, 1, 0x00050008),
     A.NOT_MAPPABLE),
    ("controlword is 16 bits, not 32", RPDO1_UNMAPPED, (0x1600, 1, 0x60400020),
     A.PARAMETER_INCOMPATIBLE),
    ("five entries in a four-entry map", RPDO1_UNMAPPED, (0x1600, 0, 5), A.PDO_LENGTH),
    ("80 bits in one RPDO", (*RPDO1_UNMAPPED, (0x1600, 1, 0x607A0020),
                             (0x1600, 2, 0x60FF0020), (0x1600, 3, 0x60400010)),
     (0x1600, 0, 3), A.PDO_LENGTH),
    ("CAN-ID of a valid TPDO", (), (0x1800, 1, 0x000001A2), A.VALUE_RANGE),
    ("29-bit CAN-ID", TPDO2_OFF, (0x1801, 1, 0x20000282), A.VALUE_RANGE),
    ("bits 11-28 set", TPDO2_OFF, (0x1801, 1, 0x00000A82), A.VALUE_RANGE),
    ("restricted CAN-ID (SDO)", TPDO2_OFF, (0x1801, 1, 0x00000602), A.VALUE_RANGE),
    ("TPDO1's CAN-ID", TPDO2_OFF, (0x1801, 1, 0x00000182), A.PARAMETER_INCOMPATIBLE),
    ("the EMCY's CAN-ID", TPDO2_OFF, (0x1801, 1, 0x00000082), A.PARAMETER_INCOMPATIBLE),
    ("transmission type 241 reserved", (), (0x1400, 2, 241), A.VALUE_RANGE),
    ("RTR-only TPDO", (), (0x1800, 2, 252), A.VALUE_RANGE),
    ("inhibit time of a valid TPDO", (), (0x1800, 3, 10), A.VALUE_RANGE),
    ("the drive cannot produce SYNC", (), (0x1005, 0, 0x40000080), A.VALUE_RANGE),
    ("SYNC on a restricted CAN-ID", (), (0x1005, 0, 0x00000701), A.VALUE_RANGE),
    ("EMCY CAN-ID while EMCY is valid", (), (0x1014, 0, 0x000000A2), A.VALUE_RANGE),
    ("modes of operation 6 (homing)", (), (0x6060, 0, 6), A.VALUE_RANGE),
    ("statusword by SDO", (), (0x6041, 0, 1), A.READ_ONLY),
]


@pytest.mark.parametrize(("what", "before", "write", "code"), DRIVE_CASES,
                         ids=[case[0] for case in DRIVE_CASES])
def test_drive_refuses_with_the_cia301_abort_code(
        what: str, before: tuple[tuple[int, int, int], ...], write: tuple[int, int, int],
        code: SdoAbort) -> None:
    loop, _ = drive_loop()
    master = loop.master
    for index, sub, value in before:
        sdo_write(master, index, sub, value)
    index, sub, value = write
    try:
        old = sdo_read(master, index, sub)
    except (KeyError, canopen.SdoAbortedError):
        old = None
    with pytest.raises(canopen.SdoAbortedError) as info:
        sdo_write(master, index, sub, value)
    assert hex(info.value.code) == hex(code), what
    if old is not None:
        assert sdo_read(master, index, sub) == old                # nothing was stored
    if 0x1005 <= index <= 0x1BFF and code not in (A.NO_OBJECT, A.READ_ONLY, A.NO_SUB_INDEX):
        refused = loop.device.refused[-1]
        assert (refused.index, refused.subindex, refused.code) == (index, sub, code)
        assert f"0x{index:04X}:{sub:02X}" in str(refused)


def test_the_cia301_remapping_sequence_is_accepted_step_by_step() -> None:
    loop, _ = drive_loop()
    master = loop.master
    for index, sub, value in ((0x1400, 1, 0x80000202), (0x1600, 0, 0),
                              (0x1600, 1, 0x607A0020), (0x1600, 2, 0x60400010),
                              (0x1600, 0, 2), (0x1400, 2, 255), (0x1400, 1, 0x00000222)):
        sdo_write(master, index, sub, value)
    assert loop.device.refused == []
    master.rpdo.read()
    assert master.rpdo[1].cob_id == 0x222 and master.rpdo[1].trans_type == 255
    assert [v.index for v in master.rpdo[1]] == [0x607A, 0x6040]


# ------------------------------------------------------------------ the analog output module
def module_loop() -> Loopback:
    cfg = load_fertilizer_config()
    wiring = cfg.wiring
    module = AnalogOutputModule(wiring.analog_output_node_id, wiring.analog_output_eds_file,
                                AnalogOutputChannel(cfg.analog_output, np.random.default_rng(0)),
                                wiring.analog_output_channel)
    return Loopback(module, wiring.analog_output_eds_file, module.update)


MODULE_CASES = [
    ("output above 10 V", (), (0x6411, 1, 12000), A.VALUE_TOO_HIGH),
    ("output below 0 V", (), (0x6411, 2, -5), A.VALUE_TOO_LOW),
    ("no third output", (), (0x6411, 3, 0), A.NO_SUB_INDEX),
    ("error mode 2", (), (0x6443, 1, 2), A.VALUE_TOO_HIGH),
    ("error value above 10 V", (), (0x6444, 1, 10001), A.VALUE_TOO_HIGH),
    ("error behaviour 3", (), (0x1029, 1, 3), A.VALUE_TOO_HIGH),
    ("consumer heartbeat of node 200", (), (0x1016, 1, 0x00C8012C), A.VALUE_RANGE),
    ("consumer heartbeat reserved bits", (), (0x1016, 1, 0x0110012C), A.VALUE_RANGE),
    ("RPDO1 maps two entries, not three", ((0x1400, 1, 0x80000220), (0x1600, 0, 0)),
     (0x1600, 3, 0x64110110), A.NO_SUB_INDEX),
    ("count 3 of a two-entry map", ((0x1400, 1, 0x80000220), (0x1600, 0, 0)),
     (0x1600, 0, 3), A.PDO_LENGTH),
    ("error mode is not mappable", ((0x1400, 1, 0x80000220), (0x1600, 0, 0)),
     (0x1600, 1, 0x64430108), A.NOT_MAPPABLE),
    ("mapping the valid RPDO1", (), (0x1600, 1, 0x64110210), A.DEVICE_STATE),
    ("no TPDO on the module", (), (0x1800, 1, 0x000001A0), A.NO_OBJECT),
]


@pytest.mark.parametrize(("what", "before", "write", "code"), MODULE_CASES,
                         ids=[case[0] for case in MODULE_CASES])
def test_analog_module_refuses_with_the_cia301_abort_code(
        what: str, before: tuple[tuple[int, int, int], ...], write: tuple[int, int, int],
        code: SdoAbort) -> None:
    loop = module_loop()
    for index, sub, value in before:
        sdo_write(loop.master, index, sub, value)
    index, sub, value = write
    with pytest.raises(canopen.SdoAbortedError) as info:
        sdo_write(loop.master, index, sub, value)
    assert hex(info.value.code) == hex(code), what


def test_analog_module_takes_values_within_its_limits() -> None:
    loop = module_loop()
    master = loop.master
    master.sdo[0x6411][1].raw = 10000
    master.sdo[0x6443][2].raw = 0
    master.sdo[0x1029][1].raw = 2
    assert (master.sdo[0x6411][1].raw, master.sdo[0x6443][2].raw,
            master.sdo[0x1029][1].raw) == (10000, 0, 2)
    assert loop.device.refused == []


# ------------------------------------------------------------------ rules neither EDS reaches
def _od_with_wo_object_and_two_consumers() -> canopen.ObjectDictionary:
    """An object dictionary with what neither shipped EDS has: a write-only mappable object and
    a consumer heartbeat of two entries (plus TPDO1 to map into)."""
    od = canopen.ObjectDictionary()

    def var(index: int, sub: int, name: str, data_type: int, access: str,
            default: int, mappable: bool = False) -> ODVariable:
        v = ODVariable(name, index, sub)
        v.data_type, v.access_type, v.default, v.pdo_mappable = (data_type, access, default,
                                                                  mappable)
        return v

    command = var(0x2000, 0, "Command", datatypes.UNSIGNED16, "wo", 0, mappable=True)
    od.add_object(command)
    consumer = ODRecord("Consumer heartbeat time", 0x1016)
    consumer.add_member(var(0x1016, 0, "Highest sub-index", datatypes.UNSIGNED8, "ro", 2))
    consumer.add_member(var(0x1016, 1, "Consumer 1", datatypes.UNSIGNED32, "rw", 0x0010012C))
    consumer.add_member(var(0x1016, 2, "Consumer 2", datatypes.UNSIGNED32, "rw", 0))
    od.add_object(consumer)
    com = ODRecord("TPDO1 communication parameter", 0x1800)
    com.add_member(var(0x1800, 1, "COB-ID", datatypes.UNSIGNED32, "rw", 0x80000185))
    od.add_object(com)
    mapping = ODRecord("TPDO1 mapping parameter", 0x1A00)
    mapping.add_member(var(0x1A00, 0, "Count", datatypes.UNSIGNED8, "rw", 0))
    mapping.add_member(var(0x1A00, 1, "Entry 1", datatypes.UNSIGNED32, "rw", 0))
    od.add_object(mapping)
    return od


def test_guard_refuses_a_write_only_object_in_a_tpdo_and_a_node_watched_twice() -> None:
    od = _od_with_wo_object_and_two_consumers()
    values = {(o.index, o.subindex): o.default for o in
              (od[0x1016][1], od[0x1016][2], od[0x1800][1], od[0x1A00][0])}
    guard = CommunicationGuard(od, lambda index, sub: values[(index, sub)])
    with pytest.raises(ConfigRefused) as info:
        guard.check(0x1A00, 1, 0x20000010)
    assert info.value.code == A.NOT_MAPPABLE and "a TPDO cannot read it" in info.value.reason
    with pytest.raises(ConfigRefused) as info:
        guard.check(0x1016, 2, 0x001000C8)                 # node 0x10 again, 200 ms
    assert info.value.code == A.PARAMETER_INCOMPATIBLE
    guard.check(0x1016, 2, 0x001100C8)                     # another node: accepted
    guard.check(0x1016, 2, 0x00100000)                     # node 0x10 with time 0: off
