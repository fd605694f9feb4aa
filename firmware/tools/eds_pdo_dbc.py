"""Write the PDOs of a CANopen EDS as a DBC, so their C pack/unpack code can be generated.

The PDO layout lives in the EDS (communication 0x1400/0x1800, mapping 0x1600/0x1A00); this turns
each default mapping into a DBC message (RPDOn / TPDOn, COB-ID with $NODEID expanded) whose
signals are the mapped objects, little-endian, signed as their CANopen data type. Used by
firmware/generate.sh; needs canopen and cantools.

    python eds_pdo_dbc.py EDS NODE_ID OUT.dbc
"""

from __future__ import annotations

import re
import sys

import canopen
import cantools
from canopen.objectdictionary import datatypes
from cantools.database.can import Database, Message, Node, Signal

SIGNED = {datatypes.INTEGER8, datatypes.INTEGER16, datatypes.INTEGER32, datatypes.INTEGER64}


def signal_name(name: str) -> str:
    """'Target velocity' -> 'TargetVelocity'."""
    return "".join(word[:1].upper() + word[1:] for word in re.split(r"[^A-Za-z0-9]+", name))


def pdo_messages(od: canopen.ObjectDictionary, comm_base: int, kind: str,
                 sender: str, receiver: str) -> list[Message]:
    out = []
    for n in range(512):
        if comm_base + n not in od:
            break
        comm, mapping = od[comm_base + n], od[comm_base + 0x200 + n]
        cob_id = int(comm[1].default) & 0x7FF
        signals, start = [], 0
        for sub in range(1, int(mapping[0].default) + 1):
            entry = int(mapping[sub].default)
            index, subindex, bits = entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF
            obj = od[index] if subindex == 0 and not hasattr(od[index], "subindices") \
                else od[index][subindex]
            signals.append(Signal(name=signal_name(obj.name), start=start, length=bits,
                                  byte_order="little_endian",
                                  is_signed=obj.data_type in SIGNED, receivers=[receiver],
                                  comment=f"0x{index:04X} sub {subindex}: {obj.name}"))
            start += bits
        out.append(Message(frame_id=cob_id, name=f"{kind}{n + 1}", length=(start + 7) // 8,
                           signals=signals, senders=[sender],
                           comment=f"{kind}{n + 1} of the drive (EDS 0x{comm_base + n:04X}), "
                                   f"transmission type {int(comm[2].default)}"))
    return out


def main(argv: list[str]) -> int:
    if len(argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    eds, node_id, out = argv[1], int(argv[2], 0), argv[3]
    od = canopen.import_od(eds, node_id=node_id)
    messages = (pdo_messages(od, 0x1400, "RPDO", "Master", "Drive")
                + pdo_messages(od, 0x1800, "TPDO", "Drive", "Master"))
    db = Database(messages=messages, nodes=[Node("Master"), Node("Drive")],
                  version=f"PDOs of {eds.rsplit('/', 1)[-1]}, node {node_id}")
    cantools.database.dump_file(db, out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
