"""A few dozen lines of C join the software bus (the firmware's way in, without kernel CAN)."""

from __future__ import annotations

import shutil
import subprocess
import time
from pathlib import Path

import can
import pytest

from hil.bus import open_bus
from hil.softbus import SoftwareBus

SOURCE = Path(__file__).resolve().parents[2] / "helpers" / "softbus_client.c"


def test_minimal_c_client_exchanges_frames(tmp_path: Path) -> None:
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler on this machine")
    binary = tmp_path / "softbus_client"
    subprocess.run([cc, "-std=c11", "-D_POSIX_C_SOURCE=200809L", "-Wall", "-Wextra", "-Werror",
                    "-o", str(binary), str(SOURCE)], check=True)
    with SoftwareBus(port=0) as softbus:
        peer = open_bus(softbus.spec())
        try:
            proc = subprocess.Popen([str(binary), str(softbus.port)], stdout=subprocess.PIPE,
                                    text=True)
            got = peer.recv(5.0)
            assert got is not None and got.arbitration_id == 0x123
            assert bytes(got.data) == b"\xde\xad" and not got.is_extended_id
            time.sleep(0.1)   # let the C client's rawmode hold pass
            peer.send(can.Message(arbitration_id=0x18FEF100, data=b"\x01\x02",
                                  is_extended_id=True))
            out, _ = proc.communicate(timeout=10)
        finally:
            peer.shutdown()
    assert proc.returncode == 0
    assert out.strip() == "18FEF100 0102"
