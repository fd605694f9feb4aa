"""``hil isobus serve --vt``: the VT beside the TECU and the TC, its record, the browser page."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path

import can

from hil.isobus.field import load_field
from hil.isobus.serve import ServeVt, serve
from hil.isobus.tractor import Tractor, TractorSetup

ROOT = Path(__file__).resolve().parents[4]
FIELD = ROOT / "plant_emulators" / "fertilizer" / "fields" / "field-rect.geojson"


def _hil(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "hil", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=120)


def test_serve_with_the_vt(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = _hil("isobus", "serve", "--bus", "virtual:serve-vt", "--path", str(FIELD),
                "--no-map", "--duration", "1.5", "--drive-after", "0", "--vt",
                "--vt-browser", "0", "--out", str(out), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "the VT in the browser: http://127.0.0.1:" in done.stdout
    frames = list(can.LogReader(out / "bus.log"))
    claims = {f.arbitration_id & 0xFF for f in frames
              if (f.arbitration_id >> 8) & 0x3FF00 == 0xEE00}
    assert claims == {0x80, 0xF7, 0x26}
    status = [f for f in frames if f.arbitration_id & 0xFF == 0x26
              and (f.arbitration_id >> 8) & 0x3FF00 == 0xE600 and f.data[0] == 0xFE]
    assert status, "no VT status from 0x26"
    record = json.loads((out / "vt" / "vt.json").read_text())
    assert record["vt_version"] == 4 and record["working_sets"] == []


def test_a_browser_port_in_use_is_refused_naming_it(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = _hil("isobus", "serve", "--bus", "virtual:serve-vt2", "--path", str(FIELD),
                    "--no-map", "--duration", "1", "--vt-browser", str(port), "--out",
                    str(tmp_path / "o"), cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert f"127.0.0.1:{port}" in done.stderr and "Traceback" not in done.stderr


# --------------------------------------------------------------------- through the staging
def _tractor() -> Tractor:
    return Tractor(TractorSetup(field=load_field(FIELD), prescription=None, drive_after_s=0.0))


def test_the_serves_vt_goes_through_its_staging_directory(tmp_path: Path) -> None:
    """``vt/`` is one of the serve's outputs: drawn into the staging directory while it runs
    (never into ``out`` directly), moved in at the end with ``vt.json``; a later serve without
    the VT takes the old folder away with the rest of the previous run."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "vt").mkdir()
    (out / "vt" / "screen-0001.png").write_bytes(b"an earlier serve's")
    seen: list[str] = []

    def console(line: str) -> None:
        seen.append(line)
        if "live files" in line:      # the staging exists: nothing of this serve in out/vt
            assert (out / "vt" / "screen-0001.png").read_bytes() == b"an earlier serve's"

    serve(_tractor(), "virtual:serve-vt-staging", out, duration_s=0.6, console=console,
          vt=ServeVt())
    assert any("live files" in line for line in seen)
    record = json.loads((out / "vt" / "vt.json").read_text())
    assert record["vt_version"] == 4 and record["working_sets"] == []
    assert not (out / "vt" / "screen-0001.png").exists()     # replaced as a set
    assert not [p for p in out.iterdir() if p.name.startswith(".serve-")]
    serve(_tractor(), "virtual:serve-vt-staging2", out, duration_s=0.1, console=None)
    assert not (out / "vt").exists() and (out / "bus.log").exists()


def test_a_serves_browser_port_in_use_leaves_out_as_it_was(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        try:
            serve(_tractor(), "virtual:serve-vt-port", out, duration_s=0.5, console=None,
                  vt=ServeVt(browser_port=port))
        except OSError as exc:
            assert f"127.0.0.1:{port}" in str(exc)
        else:
            raise AssertionError("a port in use was listened on")
    assert not out.exists()
