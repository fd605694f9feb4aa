"""agrihil-sowing-depth-isobus-fw, the C build of the depth controller's ISOBUS mode (issue 42).

* the depth vectors (``firmware/isobus/data/depth-isobus-*.frames``) are what the Python
  controller sends today (recorded again here and compared line by line), and the C build
  sends their frames byte for byte (``replay_isobus_depth``, ctest's ``isobus_depth_vectors``);
  the depth DDOP's bytes likewise (``test_iso_ddop_depth``);
* the replay fails, naming the line, on a vector with one byte changed;
* the program on the software bus claims its address and sends its status from it;
* on the rig (slow): a depth ``[tractor]`` run in lockstep gives the same DUT frames from the
  firmware on the software bus as from the Python mode in process, the firmware qualifies on
  the depth rig's isobus suite, and with its must-fail parameter ``fallback = "hold"`` it fails
  the suite's TC-loss run.
"""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys
import tty
from pathlib import Path

import pytest

from hil.softbus import SoftwareBus
from reference_controllers.vectors.isobus_depth import (
    DATA_DIR,
    DDOP_FILE,
    SUFFIX,
    ddop_lines,
    record,
    scenarios,
)
from tests.helpers.fresh_vectors import assert_vector_file_fresh

ROOT = Path(__file__).resolve().parents[2]
HIL = str(Path(sys.executable).with_name("hil"))
APP = "agrihil-sowing-depth-isobus-fw"
PROFILE = "sowing-depth-fuzzy-pid-isobus-firmware.toml"
TARGETS = (APP, "replay_isobus_depth", "test_iso_ddop_depth")
#: the tractor drive takes ~3 s of CPU, a scripted run ~0.6 s: one scripted run in the default set
SLOW_SCENARIOS = {"depth-isobus-drive", "depth-isobus-must-fail", "depth-isobus-fixed"}


@pytest.fixture(scope="module")
def depth_isobus_bin(firmware_bin: Path) -> Path:
    """The program, the replay and the DDOP check, built in the firmware tests' cached build
    directory."""
    with (firmware_bin.parent / f"{firmware_bin.name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not all((firmware_bin / t).exists() for t in TARGETS):
            done = subprocess.run(["nice", "cmake", "--build", str(firmware_bin), "-j2",
                                   "--target", *TARGETS], capture_output=True, text=True,
                                  timeout=300)
            assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return firmware_bin / APP


@pytest.mark.parametrize("scenario", [
    pytest.param(s, id=s.name, marks=[pytest.mark.slow] if s.name in SLOW_SCENARIOS else [])
    for s in scenarios()])
def test_the_committed_depth_vectors_are_what_the_python_controller_sends(scenario) -> None:
    assert_vector_file_fresh(DATA_DIR / f"{scenario.name}{SUFFIX}", record(scenario),
                             twin="the Python controller",
                             rewrite="python -m reference_controllers.vectors.isobus_depth")


def test_the_committed_depth_ddop_is_the_python_pool() -> None:
    assert (DATA_DIR / DDOP_FILE).read_text().splitlines() == ddop_lines()


def test_the_c_build_sends_the_depth_vectors_frames_byte_for_byte(
        depth_isobus_bin: Path) -> None:
    vectors = sorted(DATA_DIR.glob(f"depth-isobus-*{SUFFIX}"))
    assert {p.stem for p in vectors} == {s.name for s in scenarios()}
    done = subprocess.run([str(depth_isobus_bin.with_name("replay_isobus_depth")),
                           *map(str, vectors)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.count(": identical") == len(vectors), done.stdout
    done = subprocess.run([str(depth_isobus_bin.with_name("test_iso_ddop_depth")),
                           str(DATA_DIR / DDOP_FILE)], capture_output=True, text=True,
                          timeout=60)
    pools = len(ddop_lines()) - 2          # two comment lines, then a pool a line
    assert done.returncode == 0 and f"{pools} pools identical" in done.stdout, \
        done.stdout + done.stderr


def test_the_replay_names_the_first_frame_the_c_build_does_not_send(
        depth_isobus_bin: Path, tmp_path: Path) -> None:
    """A vector whose reported actual depth (DDI 57) is one off fails at that line."""
    lines = (DATA_DIR / "depth-isobus-scripted-tc.frames").read_text().splitlines()
    # the first DDI 57 value (process data value command 0x3, element 1) the controller sent
    at = next(i for i, line in enumerate(lines) if line.startswith("> ")
              and line.split("#")[1].startswith("13003900"))
    frame = lines[at]
    last = int(frame[-2:], 16)
    lines[at] = f"{frame[:-2]}{(last + 1) % 256:02X}"
    bad = tmp_path / "depth-isobus-changed.frames"
    bad.write_text("\n".join(lines) + "\n")
    done = subprocess.run([str(depth_isobus_bin.with_name("replay_isobus_depth")), str(bad)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"{bad}:{at + 1} " in done.stderr, done.stderr


CLAIM = 0x18EEFF82            # address claimed (PGN 0xEE00) from 0x82, to everyone
STATUS_FROM_CLAIM = 0x18FF3082  # DepthControllerStatus from the claimed address
STATUS_FROM_DBC = 0x18FF3080    # ... from the rig DBC's 0x80: never under ISOBUS
RPDO2 = 0x302


def test_the_program_in_lockstep_claims_its_address_and_sends_its_status_from_it(
        depth_isobus_bin: Path, start_app) -> None:
    """The program itself (its loop, its parameters, its GNSS port) on the software bus: the
    first step claims 0x82 with its NAME (planters/seeders, identity 0x0D42), the status goes
    out from 0x82 once the claim settled (250 ms), never from the DBC's 0x80, and SIGTERM
    stops it with 0."""
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        with SoftwareBus(port=0) as sb:
            app = start_app(APP, sb.spec(), "--sync", "--param", "kp0=3",
                            env={"AGRIHIL_GNSS_PORT": os.ttyname(slave)}, bootup_id=0x701)
            first = app.sync({CLAIM, RPDO2})
            name = int.from_bytes(bytes(first[CLAIM].data), "little")
            assert name == 0x0D42 | 128 << 40 | 4 << 49 | 2 << 60 | 1 << 63
            seen: set[int] = set()
            for _ in range(30):
                seen |= set(app.sync({RPDO2}))
            app.drain()
            code, _ = app.terminate()
    finally:
        os.close(master)
        os.close(slave)
    assert STATUS_FROM_CLAIM in seen and STATUS_FROM_DBC not in seen, sorted(seen)
    assert code == 0, app.stderr()
    assert "GNSS on /dev/" in app.stderr() and "stopped after 31 steps" in app.stderr()


# ------------------------------------------------------------------ on the rig
SCENARIO = """
name = "isobus-depth-lockstep"
description = "the depth field run's first 30 s: connection, the drive off into the first pass"
rig = "sowing_depth"
duration_s = 30.0
seed = 42
tags = ["isobus"]

[tractor]
field = "{root}/plant_emulators/fertilizer/fields/field-rect.geojson"
prescription = "{root}/plant_emulators/sowing_depth/fields/depths-3zones.geojson"
drive_after_s = 8.0
"""


def _dut_frames(bus_log: Path) -> list[tuple[str, str]]:
    """(time, frame) of every frame the rig received from the DUT (bus.log's 'R' lines)."""
    out = []
    for line in bus_log.read_text().splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[3] == "R":
            out.append((parts[0], parts[2]))
    return out


@pytest.mark.slow
def test_on_the_rig_in_lockstep_it_sends_what_the_python_mode_sends(
        depth_isobus_bin: Path, tmp_path: Path) -> None:
    """The first 30 s of the depth field run (connection, the pool transfer, the map's depth,
    the drive) with the C firmware on the software bus and the Python mode in process: every
    frame the DUT sends, at the same run time, is the same."""
    scenario = tmp_path / "isobus-depth-lockstep.toml"
    scenario.write_text(SCENARIO.format(root=ROOT))
    runs = {}
    for name, profile, bus in (
            ("c", PROFILE, "softbus"),
            ("python", "sowing-depth-fuzzy-pid-isobus-daemon.toml", "inline")):
        out = tmp_path / name
        done = subprocess.run([HIL, "run", "--dut", str(ROOT / "dut_profiles" / profile),
                               "--scenario", str(scenario), "--bus", bus, "--out", str(out)],
                              capture_output=True, text=True, timeout=900, cwd=ROOT)
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
        runs[name] = _dut_frames(out / "bus.log")
    c, python = runs["c"], runs["python"]
    assert len(c) > 3000                           # ~4,000: a status every 10th step
    first = next((i for i, (a, b) in enumerate(zip(c, python, strict=False)) if a != b), None)
    assert first is None and len(c) == len(python), (
        f"first difference at DUT frame {first}: C {c[first:first + 3] if first else c[-3:]}, "
        f"Python {python[first:first + 3] if first else python[-3:]}")
    # the TC's depth reached it: DDI 57 reports go out from its address (0x82)
    assert any(f.startswith("0CCBF782#") or f.startswith("14CBF782#") for _, f in c), c[:50]


@pytest.mark.slow
def test_it_qualifies_on_the_depth_rig_isobus_suite(depth_isobus_bin: Path,
                                                     tmp_path: Path) -> None:
    """``hil qualify`` of the firmware profile (the isobus suite: [wiring] isobus = true) on the
    software bus: it passes, every zone of the field run included (minutes: slow)."""
    out = tmp_path / "q"
    proc = subprocess.run([sys.executable, "-m", "hil", "qualify",
                           str(ROOT / "dut_profiles" / PROFILE), "--bus", "softbus",
                           "--out", str(out), "--quiet"], cwd=ROOT, capture_output=True,
                          text=True, timeout=3600)
    record_path = out / "record.json"
    assert record_path.exists(), proc.stdout[-2000:] + proc.stderr[-2000:]
    record = json.loads(record_path.read_text())
    failed = [(m["name"], m["conditions"], m["value"]) for m in record["measurements"]
              if m["outcome"] in ("fail", "error")]
    assert proc.returncode == 0 and record["verdict"] == "pass", failed
    zones = {m["conditions"]["zone"]: m["outcome"] for m in record["measurements"]
             if m["name"] == "isobus.depth.zone_error"}
    assert zones == {"30 mm": "pass", "35 mm": "pass", "40 mm": "pass"}


@pytest.mark.slow
def test_with_fallback_hold_it_fails_the_tc_loss_run(depth_isobus_bin: Path,
                                                     tmp_path: Path) -> None:
    """The C build's must-fail parameter on the rig: ``fallback = "hold"`` keeps the TC's depth
    after the TC is lost, and the isobus suite's TC-loss run fails it on
    ``isobus.depth.tc_loss.fallback_time`` (the profile above passes it: 4.7 s)."""
    text = (ROOT / "dut_profiles" / PROFILE).read_text()
    text = text.replace('name = "sowing-depth-fuzzy-pid-isobus-firmware"',
                        'name = "sowing-depth-isobus-never-falls-back-firmware"')
    text = text.replace('database = "plant_emulators', f'database = "{ROOT}/plant_emulators')
    text = text.replace("kd0 = 0.0\n", 'kd0 = 0.0\nfallback = "hold"\n', 1)
    assert 'fallback = "hold"' in text
    profile = tmp_path / "sowing-depth-isobus-never-falls-back-firmware.toml"
    profile.write_text(text)
    out = tmp_path / "q"
    proc = subprocess.run([sys.executable, "-m", "hil", "qualify", str(profile), "--bus",
                           "softbus", "--out", str(out), "--quiet", "-k", "tc_loss"], cwd=ROOT,
                          capture_output=True, text=True, timeout=1800)
    record_path = out / "record.json"
    assert record_path.exists(), proc.stdout[-2000:] + proc.stderr[-2000:]
    record = json.loads(record_path.read_text())
    outcomes = [m["outcome"] for m in record["measurements"]
                if m["name"] == "isobus.depth.tc_loss.fallback_time"]
    assert proc.returncode == 1 and record["verdict"] == "fail"
    assert outcomes and set(outcomes) <= {"fail", "error"}, outcomes
