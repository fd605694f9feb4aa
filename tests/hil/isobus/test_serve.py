"""``hil isobus serve``: the tractor alone on a bus, its logs, and its errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import can

from hil.isobus.can_id import decode_id

ROOT = Path(__file__).resolve().parents[3]
FIELDS = ROOT / "plant_emulators" / "fertilizer" / "fields"
FIELD = FIELDS / "field-rect.geojson"
MAP = FIELDS / "rates-3zones.geojson"


def _hil(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "hil", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=120)


def test_serve_claims_sends_speeds_and_writes_its_logs(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = _hil("isobus", "serve", "--bus", "virtual:serve-test", "--path", str(FIELD),
                "--map", str(MAP), "--duration", "1.5", "--drive-after", "0", "--out", str(out),
                cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    frames = list(can.LogReader(out / "bus.log"))
    claims = {f.arbitration_id & 0xFF for f in frames
              if (f.arbitration_id >> 8) & 0x3FF00 == 0xEE00}
    assert claims == {0x80, 0xF7}
    # the TECU's speeds, from the TECU's address (their 100 ms period is checked in virtual
    # time by test_tecu.py: a wall-clock run on a shared machine is no place to time them)
    for pgn in (65096, 65097, 61474):
        sources = {decode_id(f.arbitration_id).source for f in frames
                   if decode_id(f.arbitration_id).pgn == pgn}
        assert sources == {0x80}, (pgn, sources)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["activated"] is False and summary["frames"] == len(frames)
    assert (out / "tc.jsonl").exists()


def test_a_broken_map_is_refused_naming_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "rates.geojson"
    bad.write_text('{"type": "FeatureCollection", "features": [{"type": "Feature"}]}')
    done = _hil("isobus", "serve", "--bus", "virtual:x", "--path", str(FIELD), "--map", str(bad),
                "--duration", "1", "--out", str(tmp_path / "o"), cwd=tmp_path)
    assert done.returncode == 2
    assert str(bad) in done.stderr and "Traceback" not in done.stderr


def test_options_out_of_range_are_refused(tmp_path: Path) -> None:
    for option, value in (("--wheel-slip", "1.5"), ("--duration", "-1"),
                          ("--drive-after", "nan")):
        done = _hil("isobus", "serve", "--bus", "virtual:x", "--path", str(FIELD), "--no-map",
                    option, value, "--out", str(tmp_path / "o"), cwd=tmp_path)
        assert done.returncode == 2, (option, done.stderr)
        assert option in done.stderr and "Traceback" not in done.stderr


def test_the_bus_examples_of_the_help_are_accepted(softbus) -> None:
    # the help's examples: each parses as a bus spec; the software bus one opens and carries a
    # frame when a software bus listens at its host (its port swapped for the test's own)
    from hil.bus.registry import open_bus
    from hil.cli.main import build_parser

    parser = build_parser()
    serve = parser._subparsers._group_actions[0].choices["isobus"]  # type: ignore[union-attr]
    help_text = " ".join(serve._subparsers._group_actions[0].choices["serve"]  # type: ignore
                         .format_help().split())
    examples = help_text.split("bus spec, e.g. ", 1)[1].split(" (")[0].split(", ")
    assert any(e.startswith("socketcand:") for e in examples), help_text
    for example in [*examples, "virtual:bench"]:
        if example.startswith("socketcand:"):
            example = example.replace(":29536", f":{softbus.port}")
        if example.startswith("socketcan:"):
            continue     # needs a kernel CAN interface; its form is python-can's own
        bus = open_bus(example)
        try:
            bus.send(can.Message(arbitration_id=0x18EFFF80, data=b"1", is_extended_id=True))
        finally:
            bus.shutdown()
