"""agrihil-fertilizer-isobus-fw, the C build of the fertilizer controller's ISOBUS mode.

Two things here; the frame-by-frame identity with the Python controller is ctest's
(``firmware/isobus/isobus.cmake``: ``isobus_vectors``, ``isobus_ddop``):

* the shared vectors that ctest replays are what the Python controller sends today (they are
  recorded again here and compared line by line, so a change of the Python side that the
  committed vectors do not carry fails here, not silently in the C build);
* the program, free-running on the software bus against ``hil isobus serve`` (the emulated
  tractor: TECU + Task Controller, in real time), claims its address, has its DDOP activated
  and meters the rate the TC sets.
"""

from __future__ import annotations

import fcntl
import json
import subprocess
import sys
import time
from pathlib import Path

import can
import pytest

from hil.bus import open_bus
from hil.isobus import ddi
from hil.isobus import process_data as pd
from hil.isobus.can_id import decode_id
from hil.softbus import SoftwareBus
from reference_controllers.vectors import VECTOR_DIR
from reference_controllers.vectors.isobus import DDOP_FILE, SUFFIX, ddop_lines, record, scenarios
from tests.helpers.fresh_vectors import assert_vector_file_fresh

ROOT = Path(__file__).resolve().parents[2]
HIL = str(Path(sys.executable).with_name("hil"))
FIELDS = ROOT / "plant_emulators" / "fertilizer" / "fields"
APP = "agrihil-fertilizer-isobus-fw"
HEARTBEAT = 0x710
COMMAND = 0x220
ADDRESS = 0x81
TC_ADDRESS = 0xF7


TARGETS = (APP, "replay_isobus", "test_iso_ddop")


@pytest.fixture(scope="module")
def isobus_bin(firmware_bin: Path) -> Path:
    """The ISOBUS program (and the replay and DDOP check beside it), built in the firmware
    tests' cached build directory."""
    with (firmware_bin.parent / f"{firmware_bin.name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not all((firmware_bin / t).exists() for t in TARGETS):
            done = subprocess.run(["cmake", "--build", str(firmware_bin), "-j2", "--target",
                                   *TARGETS], capture_output=True, text=True, timeout=300)
            assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return firmware_bin / APP


# ------------------------------------------------------------------ the shared vectors
#: the field drive takes ~6-13 s of CPU (the TC's coverage at every 10 ms tick): slow set
SLOW_SCENARIOS = {"isobus-drive"}


@pytest.mark.parametrize("scenario", [
    pytest.param(s, id=s.name, marks=[pytest.mark.slow] if s.name in SLOW_SCENARIOS else [])
    for s in scenarios()])
def test_the_committed_vectors_are_what_the_python_controller_sends(scenario) -> None:
    assert_vector_file_fresh(VECTOR_DIR / f"{scenario.name}{SUFFIX}", record(scenario),
                             twin="the Python controller",
                             rewrite="python -m reference_controllers.vectors.isobus")


def test_the_committed_ddop_vector_is_the_python_pool() -> None:
    assert (VECTOR_DIR / DDOP_FILE).read_text().splitlines() == ddop_lines()


def test_the_c_build_sends_the_vectors_frames_byte_for_byte(isobus_bin: Path) -> None:
    """What ctest's isobus_vectors and isobus_ddop do, in the pytest run CI makes."""
    vectors = sorted(VECTOR_DIR.glob(f"isobus-*{SUFFIX}"))
    assert {p.stem for p in vectors} == {s.name for s in scenarios()}
    done = subprocess.run([str(isobus_bin.with_name("replay_isobus")), *map(str, vectors)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.count(": identical") == len(vectors), done.stdout
    done = subprocess.run([str(isobus_bin.with_name("test_iso_ddop")),
                           str(VECTOR_DIR / DDOP_FILE)], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0 and "18 pools identical" in done.stdout, done.stdout + done.stderr


# ------------------------------------------------------------------ end to end
def _frames_until(bus: can.BusABC, proc: subprocess.Popen[bytes], seconds: float,
                  ) -> list[can.Message]:
    frames = []
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and proc.poll() is None:
        msg = bus.recv(0.05)
        if msg is not None:
            frames.append(msg)
    return frames


def _process_data(frames: list[can.Message], source: int, destination: int,
                  ) -> list[tuple[can.Message, pd.ProcessDataMessage]]:
    out = []
    for f in frames:
        fid = decode_id(f.arbitration_id)
        if f.is_extended_id and fid.pgn == pd.PROCESS_DATA_PGN and fid.source == source \
                and fid.destination == destination:
            out.append((f, pd.decode(bytes(f.data))))
    return out


def _volts(frames: list[can.Message]) -> list[int]:
    return [int.from_bytes(bytes(f.data[:2]), "little") for f in frames
            if not f.is_extended_id and f.arbitration_id == COMMAND]


def test_against_hil_isobus_serve_it_claims_connects_and_meters_the_tcs_rate(
        isobus_bin: Path, tmp_path: Path) -> None:
    """~8 s of wall time: the firmware connects within ~2 s while the tractor drives off
    (after 0.5 s); its sections come on where the path enters the work area (~4.7 s)."""
    out = tmp_path / "serve"
    with SoftwareBus(port=0) as sb:
        bus = open_bus(sb.spec())
        firmware = subprocess.Popen([str(isobus_bin), "--bus", sb.spec(), "--period-ms", "100"],
                                    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.PIPE)
        serve = subprocess.Popen(
            [HIL, "isobus", "serve", "--bus", sb.spec(),
             "--path", str(FIELDS / "field-rect.geojson"),
             "--map", str(FIELDS / "rates-3zones.geojson"), "--drive-after", "0.5",
             "--duration", "7", "--out", str(out), "--quiet"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            frames = _frames_until(bus, serve, 60.0)
        finally:
            firmware.terminate()
            _, err = firmware.communicate(timeout=5)
            serve.wait(10)
            bus.shutdown()
    assert serve.returncode == 0, serve.stderr.read().decode() if serve.stderr else ""
    stderr = err.decode()
    assert firmware.returncode == 0, stderr
    # the TC's side (hil isobus serve's record): the DDOP activated, not refused
    summary = json.loads((out / "summary.json").read_text())
    assert summary["activated"], summary
    log = [json.loads(line) for line in (out / "tc.jsonl").read_text().splitlines()]
    events = [e["event"] for e in log if e["kind"] == "event" and e["address"] == ADDRESS]
    assert "activated" in events and "refused" not in events, events
    # the firmware's side: one connection, as it says when it stops
    assert "TC client connected, 1 connection(s)" in stderr, stderr
    # on the bus: its address claim is the first frame it sends from its address
    ours = [f for f in frames if f.is_extended_id and f.arbitration_id & 0xFF == ADDRESS]
    assert ours and decode_id(ours[0].arbitration_id).pgn == 0xEE00, ours[:3]
    # the TC's rate set-point arrives and the meter runs after it, not before
    rates = [f for f, m in _process_data(frames, TC_ADDRESS, ADDRESS)
             if isinstance(m, pd.ElementCommand) and m.command == pd.Command.VALUE
             and m.ddi == ddi.SETPOINT_MASS_PER_AREA_RATE and m.value > 0]
    assert rates, "the TC sent no rate set-point"
    first_rate = next(i for i, f in enumerate(frames) if f is rates[0])
    before, after = _volts(frames[:first_rate]), _volts(frames[first_rate:])
    assert before and set(before) == {0}, before
    assert after and max(after) > 0, after
    # and it reports the boom metering (actual work state 1) to the TC
    work_states = [e["value"] for e in log if e["kind"] == "value" and e["address"] == ADDRESS
                   and e["ddi"] == ddi.ACTUAL_WORK_STATE]
    assert work_states and work_states[-1] == 1, work_states


# ------------------------------------------------------------------ on the rig
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
        isobus_bin: Path, tmp_path: Path) -> None:
    """The fertilizer rig's isobus-speed-loss scenario (40 s: connection, metering at 8 km/h,
    the TECU falling silent) with the C firmware on the software bus and with the Python mode
    in process: every frame the DUT sends, at the same run time, is the same (~20 s)."""
    python_profile = tmp_path / "fertilizer-piecewise-pid-isobus-inprocess.toml"
    python_profile.write_text(f'''
[dut]
name = "fertilizer-piecewise-pid-isobus-inprocess"
version = "1.0.0"
kind = "daemon"
rig = "fertilizer"
controller = "piecewise-pid"
[launch]
command = ["{{python}}", "-m", "reference_controllers.daemon", "--controller",
           "fertilizer-piecewise-pid-isobus", "--bus", "{{bus}}", "{{params}}"]
lockstep_args = ["--sync"]
realtime_args = ["--period-ms", "100"]
inprocess = "reference_controllers.inprocess:fertilizer_piecewise_pid_isobus"
ready = "bootup"
[wiring]
node_id = 0x10
command_ids = [0x220]
database = "{ROOT / 'plant_emulators' / 'fertilizer' / 'db' / 'fertilizer.dbc'}"
[timing]
control_period_ms = 100
heartbeat_period_ms = 100
[parameters]
mode = "physical"
ff_coeff = 4.390
[rig]
flow_sensor = {{ mode = "sliding" }}
''')
    runs = {}
    for name, profile, bus in (
            ("c", ROOT / "dut_profiles" / "fertilizer-piecewise-pid-isobus-firmware.toml",
             "softbus"),
            ("python", python_profile, "inline")):
        out = tmp_path / name
        done = subprocess.run([HIL, "run", "--dut", str(profile), "--scenario",
                               "isobus-speed-loss", "--bus", bus, "--out", str(out)],
                              capture_output=True, text=True, timeout=300, cwd=ROOT)
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
        runs[name] = _dut_frames(out / "bus.log")
    c, python = runs["c"], runs["python"]
    assert len(c) > 1000
    first = next((i for i, (a, b) in enumerate(zip(c, python, strict=False)) if a != b), None)
    assert first is None and len(c) == len(python), (
        f"first difference at DUT frame {first}: C {c[first:first + 3] if first else c[-3:]}, "
        f"Python {python[first:first + 3] if first else python[-3:]}")
    volts = [int(f.split("#")[1][2:4] + f.split("#")[1][:2], 16) for _, f in c
             if f.startswith("220#")]
    assert max(volts) > 0 and volts[-1] == 0      # it metered, and stopped without speed
