"""``hil isobus serve`` writes as every command that writes into ``--out`` does (issue 30):
staged while it runs, moved in when it ends however it ends, the previous run kept until then,
and a disk that refuses a write named, with what was recorded kept."""

from __future__ import annotations

import json
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import can

ROOT = Path(__file__).resolve().parents[3]
FIELD = ROOT / "plant_emulators" / "fertilizer" / "fields" / "field-rect.geojson"
PREVIOUS = {"run_time_s": 1.0, "frames": 1, "events": 0, "values": 0, "activated": False,
            "interrupted": False}


def _serve(out: Path, *extra: str, bus: str = "virtual:staging-test",
           **kwargs: object) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "hil", "isobus", "serve", "--bus", bus, "--path", str(FIELD),
         "--no-map", "--drive-after", "0", "--out", str(out), *extra],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        **kwargs)  # type: ignore[call-overload]


def _previous_run(out: Path) -> None:
    out.mkdir()
    (out / "summary.json").write_text(json.dumps(PREVIOUS))
    (out / "bus.log").write_text("(1.000000) can0 18EEFF80#0000000000000000 T\n")
    (out / "as-applied.geojson").write_text('{"type": "FeatureCollection", "features": []}')


def test_a_running_serve_keeps_the_previous_run_and_says_it_has_not_finished(
        tmp_path: Path) -> None:
    out = tmp_path / "out"
    _previous_run(out)
    serve = _serve(out, "--duration", "60")
    try:
        # the console names the live files once the staging exists
        line = serve.stdout.readline() if serve.stdout else ""
        while "live files" not in line and serve.poll() is None:
            line = serve.stdout.readline() if serve.stdout else ""
        assert "live files" in line, serve.stderr.read() if serve.stderr else ""
        staged = [p for p in out.iterdir() if p.name.startswith(".serve-")]
        assert len(staged) == 1
        # while it runs: out says "not finished", the previous summary and log are kept
        assert json.loads((out / "summary.json").read_text())["status"] == "running"
        assert json.loads((out / "summary.previous.json").read_text()) == PREVIOUS
        assert (out / "bus.log").read_text().startswith("(1.000000)")
        deadline = time.monotonic() + 60
        while (not (staged[0] / "bus.log").exists()
               or not (staged[0] / "bus.log").stat().st_size) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert (staged[0] / "bus.log").stat().st_size > 0   # live: frames are on disk
    finally:
        serve.send_signal(signal.SIGINT)
        _, err = serve.communicate(timeout=60)
    assert serve.returncode == 130, err    # hil's exit for an interrupted command
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["frames"] > 0
    frames = list(can.LogReader(out / "bus.log"))
    assert len(frames) == summary["frames"]
    # no implement connected: no as-applied map, and the previous run's is not left beside
    assert not (out / "as-applied.geojson").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".serve-")]


def test_a_serve_that_cannot_start_leaves_out_as_it_was(tmp_path: Path) -> None:
    out = tmp_path / "out"
    _previous_run(out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    serve = _serve(out, "--duration", "1", bus="socketcand:127.0.0.1:1:can0")
    _, err = serve.communicate(timeout=60)
    assert serve.returncode == 2 and "Traceback" not in err, err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def _limit_file_size() -> None:
    limit = 1024     # under a second of the tractor's frames in candump text
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))


def test_a_disk_that_refuses_the_log_ends_the_serve_naming_it_and_keeps_what_was_recorded(
        tmp_path: Path) -> None:
    out = tmp_path / "out"
    _previous_run(out)
    serve = _serve(out, "--duration", "120", preexec_fn=_limit_file_size)
    _, err = serve.communicate(timeout=180)
    assert serve.returncode == 2, err
    assert "Traceback" not in err, err
    line = err.strip().splitlines()[-1]
    assert line.startswith("hil: error: ") and "File too large" in line, line
    assert str(out / "bus.log") in line, line
    # what was recorded until the refusal is in out, readable to its last whole line, and the
    # summary says why
    frames = list(can.LogReader(out / "bus.log"))
    assert frames and (out / "bus.log").read_bytes().endswith(b"\n")
    summary = json.loads((out / "summary.json").read_text())
    assert "File too large" in summary["error"] and summary["run_time_s"] < 120
    assert json.loads((out / "summary.previous.json").read_text()) == PREVIOUS
    assert not [p for p in out.iterdir() if p.name.startswith(".serve-")]
