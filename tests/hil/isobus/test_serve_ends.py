"""``hil isobus serve`` ends with a final ``summary.json`` however it ends (issue 43, item 1): an
exception, a signal (SIGTERM, SIGHUP), and never because of what a client sent."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
from pathlib import Path

import can
import pytest

from hil.isobus.can_id import decode_id
from hil.isobus.ddop.samples import section_control_pool
from hil.isobus.field import load_field
from hil.isobus.name import IsobusName
from hil.isobus.network import IsobusNetwork
from hil.isobus.serve import serve
from hil.isobus.tc_client import TaskControllerClient
from hil.isobus.tecu import PGN_WHEEL_BASED_SPEED
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.wire import drive

ROOT = Path(__file__).resolve().parents[3]
FIELD = ROOT / "plant_emulators" / "fertilizer" / "fields" / "field-rect.geojson"
BROKEN = IsobusName(identity_number=10, manufacturer_code=300, function=130, device_class=5)


def _tractor() -> Tractor:
    return Tractor(TractorSetup(load_field(FIELD), drive_after_s=100.0))


def _final(out: Path) -> dict:
    assert not [p for p in out.iterdir() if p.name.startswith(".serve-")], "staging left"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] != "running", summary
    return summary


def test_an_exception_inside_the_serve_leaves_a_final_summary(tmp_path: Path) -> None:
    tractor = _tractor()
    truth = tractor.tecu.truth

    def failing(t: float):
        if t > 0.5:
            raise RuntimeError("a bug in the rig")
        return truth(t)

    tractor.tecu.truth = failing
    with pytest.raises(RuntimeError, match="a bug in the rig"):
        serve(tractor, "virtual:serve-ends-1", tmp_path / "out", duration_s=10.0, console=None)
    summary = _final(tmp_path / "out")
    assert summary["status"] == "error" and "a bug in the rig" in summary["error"]
    assert summary["frames"] > 0 and summary["tc_address"] == 0xF7
    assert list(can.LogReader(tmp_path / "out" / "bus.log"))


@pytest.mark.parametrize(("signum", "name"), [(signal.SIGTERM, "SIGTERM"),
                                              (signal.SIGHUP, "SIGHUP")])
def test_a_signal_ends_the_serve_with_a_final_summary(tmp_path: Path, signum: int,
                                                       name: str) -> None:
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "hil", "isobus", "serve", "--bus", "virtual:serve-ends-2",
         "--path", str(FIELD), "--no-map", "--duration", "60", "--out", str(out)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = ""
        while "live files" not in line and proc.poll() is None:
            line = proc.stdout.readline() if proc.stdout else ""
        assert "live files" in line
    finally:
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    summary = _final(out)
    assert summary["status"] == "interrupted" and summary["signal"] == name, summary


def test_no_client_input_ends_the_serve(tmp_path: Path) -> None:
    # a client whose pool has a section without a working width: refused at activation with
    # the standard's codes; the serve runs its duration, the TECU's speeds never stop
    pool = section_control_pool(sections=2, section_width_mm=0, name=BROKEN.value)
    net = IsobusNetwork(name="broken implement")
    port = net.add(BROKEN, 0x86, "implement")
    client = TaskControllerClient(port, pool, on_setpoint=lambda *a: None,
                                  read_value=lambda *a: 0)
    port.run(client)
    stop = threading.Event()
    bus = can.Bus(interface="virtual", channel="serve-ends-3", receive_own_messages=False)

    def run_client() -> None:
        t = 0.0
        while not stop.is_set() and t < 30.0:
            t = drive(net, bus, 0.1, start_s=t)

    peer = threading.Thread(target=run_client, name="broken-implement")
    peer.start()
    try:
        result = serve(_tractor(), "virtual:serve-ends-3", tmp_path / "out", duration_s=4.0,
                       console=None)
    finally:
        stop.set()
        peer.join(timeout=10)
        bus.shutdown()
    assert not result.interrupted and result.run_time_s >= 4.0
    summary = _final(tmp_path / "out")
    assert summary["status"] == "finished", summary
    assert summary["event_counts"].get("refused", 0) >= 1, summary
    assert "client error" not in summary["event_counts"]
    assert client.refusal is not None and client.refusal.object_id != 0xFFFF
    lines = [json.loads(x) for x in (tmp_path / "out" / "tc.jsonl").read_text().splitlines()]
    refused_at = next(x["t"] for x in lines if x.get("event") == "refused")
    speeds = [m.timestamp for m in can.LogReader(tmp_path / "out" / "bus.log")
              if decode_id(m.arbitration_id).pgn == PGN_WHEEL_BASED_SPEED]
    first = speeds[0]
    assert any(t - first > refused_at + 1.0 for t in speeds), "the TECU went on after it"
