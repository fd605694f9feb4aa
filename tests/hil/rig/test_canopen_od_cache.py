"""Object dictionaries parsed once per EDS are each node's own copy, equal to canopen's parse.

:func:`hil.rig.canopen_device.object_dictionary` keeps the first parse of an EDS (issue 29: a
depth campaign sample parsed the drive's EDS 31 times) and hands every node an unpickled copy.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import canopen

from hil.rig.canopen_device import object_dictionary
from plant_emulators.sowing_depth.frames import EDS_PATH

IO_EDS = Path(__file__).parent / "data" / "io_module.eds"


def _entry(obj: Any) -> dict[str, Any]:
    """An entry's own attributes, its sub-entries' by sub-index (parents by name)."""
    out = {k: v for k, v in vars(obj).items() if k not in ("parent", "subindices", "names")}
    if hasattr(obj, "subindices"):
        out["subindices"] = {k: _entry(v) for k, v in obj.subindices.items()}
    return out


def _content(od: canopen.ObjectDictionary) -> dict[Any, Any]:
    return {"node_id": od.node_id, "bitrate": od.bitrate,
            "device": vars(od.device_information),
            "entries": {index: _entry(od[index]) for index in od}}


def test_a_cached_dictionary_is_canopens_parse_and_not_shared() -> None:
    for eds, node_id in ((EDS_PATH, 1), (EDS_PATH, 3), (IO_EDS, 5)):
        first = object_dictionary(eds, node_id)
        second = object_dictionary(eds, node_id)              # from the cache
        fresh = canopen.import_od(str(eds), node_id)
        assert _content(first) == _content(second) == _content(fresh)
        assert len(fresh) >= 10
        assert second is not first and second[0x1017] is not first[0x1017]
        second[0x1017].default = 12345                       # a copy: the next one is clean
        assert object_dictionary(eds, node_id)[0x1017].default == fresh[0x1017].default


def test_the_node_id_and_a_changed_file_give_their_own_parse(tmp_path: Path) -> None:
    one, three = object_dictionary(EDS_PATH, 1), object_dictionary(EDS_PATH, 3)
    assert one[0x1014].default != three[0x1014].default          # EMCY COB-ID $NODEID+0x80
    eds = tmp_path / "io.eds"
    shutil.copy(IO_EDS, eds)
    before = object_dictionary(eds, 5)
    text = eds.read_text().replace("ParameterName=TPDO1 mapping", "ParameterName=TPDO1 map")
    eds.write_text(text)
    stat = eds.stat()
    os.utime(eds, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    after = object_dictionary(eds, 5)
    assert before[0x1A00].name == "TPDO1 mapping" and after[0x1A00].name == "TPDO1 map"
