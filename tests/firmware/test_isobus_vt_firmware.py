"""The C ISOBUS firmware's operator interface on a VT (issue 39): byte for byte the Python's.

* The VT vectors (``firmware/isobus/data/vt-*.frames``, ``vt-pool.txt``) are what the Python
  implement (``reference_controllers/fertilizer/isobus_vt.py``) sends today: they are recorded
  again here and compared line by line (``tests/firmware/isobus_vt_vectors.py`` writes them);
  the C build replays them frame for frame (ctest's ``isobus_vt_vectors`` and
  ``isobus_vt_pool``, run here too as CI runs pytest).
* End to end: the C program in lockstep (``--sync``, on the software bus) against the tractor
  with the rig's VT, the scripted operator of the Python implement's test (calibration, Master,
  a lost row's alarm, Ack, Master off, a VT restart) and a meter whose flow follows each
  implement's own command: the whole bus log (tractor, TC, VT and implement) is the one of the
  Python implement in the same scenario.
"""

from __future__ import annotations

import fcntl
import importlib.util
import json
import math
import subprocess
import sys
import time
from pathlib import Path
from types import ModuleType

import can
import pytest

from hil.bus import open_bus
from hil.isobus.wire import VirtualWire
from hil.rig.device import Device
from hil.softbus import SoftwareBus
from plant_emulators.fertilizer.frames import FertilizerDatabase
from reference_controllers.fertilizer.isobus_vt import IsobusVtFlowController
from reference_controllers.fertilizer.operator_pool import IDS
from tests.helpers.fresh_vectors import assert_vector_file_fresh

ROOT = Path(__file__).resolve().parents[2]
APP = "agrihil-fertilizer-isobus-fw"
TARGETS = (APP, "replay_isobus", "test_iso_pool", "replay_isobus_net")
SYNC = can.Message(arbitration_id=0x080, is_extended_id=False, data=b"")
COMMAND = 0x220
DB = FertilizerDatabase()


def _load_recorder() -> ModuleType:
    """tests/firmware/isobus_vt_vectors.py (pytest imports tests by path, not as a package)."""
    path = Path(__file__).with_name("isobus_vt_vectors.py")
    spec = importlib.util.spec_from_file_location("isobus_vt_vectors", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


rec = _load_recorder()


@pytest.fixture(scope="module")
def isobus_bin(firmware_bin: Path) -> Path:
    """The ISOBUS program, the replay and the VT pool check, built in the firmware tests'
    cached build directory."""
    with (firmware_bin.parent / f"{firmware_bin.name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not all((firmware_bin / t).exists() for t in TARGETS):
            done = subprocess.run(["nice", "cmake", "--build", str(firmware_bin), "-j2",
                                   "--target", *TARGETS],
                                  capture_output=True, text=True, timeout=300)
            assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return firmware_bin / APP


# ------------------------------------------------------------------ the vectors
#: the tractor's TC covers the field at every 10 ms tick: its runs take a few s each
FAST = {"vt-no-memory", "vt-concurrent"}


@pytest.mark.parametrize("scenario", [
    pytest.param(s, id=s.name, marks=[] if s.name in FAST else [pytest.mark.slow])
    for s in rec.scenarios()])
def test_the_committed_vt_vectors_are_what_the_python_implement_sends(scenario) -> None:
    assert_vector_file_fresh(rec.DATA / f"{scenario.name}{rec.SUFFIX}", rec.record(scenario),
                             twin="the Python implement",
                             rewrite="python tests/firmware/isobus_vt_vectors.py")


def test_the_committed_vt_pool_file_is_the_python_pool() -> None:
    assert (rec.DATA / rec.POOL_FILE).read_text().splitlines() == rec.pool_lines()


def test_the_committed_etp_vector_is_what_the_python_network_sends() -> None:
    assert (rec.DATA / rec.ETP_FILE).read_text().splitlines() == rec.etp_lines()


def test_the_vt_vectors_cover_the_operator_path() -> None:
    """What the operator's vector holds: the pool uploaded by TP and stored, Master, the alarm,
    the calibration, the load from storage after the VT's restart (frames to the VT, 0x26)."""
    lines = (rec.DATA / "vt-operator.frames").read_text().splitlines()
    to_vt = [line[2:].split("#")[1] for line in lines
             if line.startswith("> ") and line[4:10] in ("E72681", "EC2681")]
    assert any(d.startswith("10180496") for d in to_vt)            # RTS: 1,048 bytes, TP
    assert any(d.startswith("D0") for d in to_vt)                   # store version
    assert any(d.startswith("D1") for d in to_vt)                   # load version
    assert any(d.startswith("B3501403004F4E20") for d in to_vt)     # Master "ON "
    assert any(d.startswith("AD0000EA03") for d in to_vt)           # the alarm mask


def test_the_c_build_answers_the_vt_vectors_byte_for_byte(isobus_bin: Path) -> None:
    """What ctest's isobus_vt_vectors and isobus_vt_pool do, in the pytest run CI makes."""
    vectors = sorted(p for p in rec.DATA.glob(f"vt-*{rec.SUFFIX}")
                     if p.name != rec.ETP_FILE and not p.name.startswith("vt-detect-"))
    assert {p.stem for p in vectors} == {s.name for s in rec.scenarios()}
    done = subprocess.run([str(isobus_bin.with_name("replay_isobus")), *map(str, vectors)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.count(": identical") == len(vectors), done.stdout
    done = subprocess.run([str(isobus_bin.with_name("test_iso_pool")),
                           str(rec.DATA / rec.POOL_FILE)], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0 and "17 pools identical" in done.stdout, done.stdout + done.stderr
    # ETP sending (the network layer alone: the 16-row pool, 2,075 bytes)
    done = subprocess.run([str(isobus_bin.with_name("replay_isobus_net")),
                           str(rec.DATA / rec.ETP_FILE)], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0 and ": identical" in done.stdout, done.stdout + done.stderr


def test_the_replay_fails_a_vector_the_c_build_does_not_send(isobus_bin: Path,
                                                             tmp_path: Path) -> None:
    """A VT vector with the Master's "ON " changed to "OM " is refused, naming the line."""
    lines = (rec.DATA / "vt-operator.frames").read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if "#B3501403004F4E20" in line)
    lines[at] = lines[at].replace("#B3501403004F4E20", "#B3501403004F4D20")
    bad = tmp_path / "vt-changed.frames"
    bad.write_text("\n".join(lines) + "\n")
    done = subprocess.run([str(isobus_bin.with_name("replay_isobus")), str(bad)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"vt-changed.frames:{at + 1} " in done.stderr and "B3501403004F4E20" in done.stderr


# ------------------------------------------------------------------ end to end
def _meter_frames(rows: list[int], command_mv: int) -> list[can.Message]:
    """Each row's flow module: 5 g/s per volt of the implement's last command (the same rule
    for both implements, so equal commands give equal flows)."""
    flow = round(command_mv / 1000.0 * 5.0, 2)
    return [DB.encode(f"FlowModule{row}", {
        "Flow": flow, "WindowMass": flow, "Counter": 1, "BaselineReady": 1,
        "SlidingWindow": 1, "AdcOverrange": 0, "InterceptApplied": 0, "WindowLength": 1000})
        for row in rows]


def _command_mv(frames: list[can.Message], last: int) -> int:
    for f in frames:
        if not f.is_extended_id and f.arbitration_id == COMMAND:
            last = int.from_bytes(bytes(f.data[:2]), "little", signed=True)
    return last


class PythonImplement(Device):
    """The Python implement stepping on SYNC, its meter's flow following its command."""

    def __init__(self) -> None:
        self.ctl = IsobusVtFlowController("physical", {})
        self.silent: set[int] = set()
        self._mv = 0
        self._boot = self.ctl.on_start()

    def next_due(self, time_s: float) -> float:
        return max(self.ctl.steps * 0.1, math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        for f in _meter_frames(sorted(self.ctl.rows.active - self.silent), self._mv):
            self.ctl.on_frame(f)
        out = self._boot + self.ctl.on_frame(SYNC)
        self._boot = []
        self._mv = _command_mv(out, self._mv)
        return out

    def accepts(self, msg: can.Message) -> bool:
        return bool(msg.is_extended_id)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        return self.ctl.on_frame(msg)


class FirmwareImplement(Device):
    """The C program in lockstep on a software bus: the wire's frames are handed to it, each
    step sends its meter's frames and a SYNC and takes what it sends, up to its command."""

    def __init__(self, bus: can.BusABC, proc: subprocess.Popen[bytes]) -> None:
        self.bus = bus
        self.proc = proc
        self.silent: set[int] = set()
        self.steps = 0
        self.sections = [1, 2, 3, 4]
        self._mv = 0
        self._boot = self._take(lambda f: not f.is_extended_id and f.arbitration_id == 0x710)

    def _take(self, last: object) -> list[can.Message]:
        frames: list[can.Message] = []
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            msg = self.bus.recv(0.5)
            if msg is None:
                assert self.proc.poll() is None, "the firmware stopped"
                continue
            frames.append(can.Message(arbitration_id=msg.arbitration_id, data=bytes(msg.data),
                                      is_extended_id=msg.is_extended_id))
            if last(msg):  # type: ignore[operator]
                return frames
        raise AssertionError(f"the firmware did not finish step {self.steps}: {frames[-3:]}")

    def next_due(self, time_s: float) -> float:
        return max(self.steps * 0.1, math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        rows = [r for r in self.sections if r not in self.silent]
        for f in [*_meter_frames(rows, self._mv), SYNC]:
            self.bus.send(f)
        out = self._boot + self._take(
            lambda f: not f.is_extended_id and f.arbitration_id == COMMAND)
        self._boot = []
        self.steps += 1
        self._mv = _command_mv(out, self._mv)
        return out

    def accepts(self, msg: can.Message) -> bool:
        return bool(msg.is_extended_id)

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        self.bus.send(msg)
        return []


def _log(wire: VirtualWire) -> list[tuple[float, int, str]]:
    return [(f.time_s, f.sender, rec.frame_text(f.frame)) for f in wire.frames]


@pytest.fixture(scope="module")
def python_run() -> tuple[list[tuple[float, int, str]], list[tuple[str, float]]]:
    """The Python implement in the operator's scenario: (bus log, the VT's events)."""
    python = PythonImplement()
    _, vt, _, wire = rec.operator_scenario(python,
                                           silence=lambda rows: python.silent.update(rows))
    return _log(wire), [(e.kind, e.time_s) for e in vt.events]


def _firmware_run(isobus_bin: Path, params: list[str]) -> tuple[
        list[tuple[float, int, str]], object, str]:
    """The C program (``--param`` each of ``params``) in the operator's scenario: (bus log,
    the VT, the program's stderr)."""
    with SoftwareBus(port=0) as sb:
        bus = open_bus(sb.spec())
        args = [a for p in params for a in ("--param", p)]
        proc = subprocess.Popen([str(isobus_bin), "--bus", sb.spec(), "--sync", *args],
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE)
        try:
            firmware = FirmwareImplement(bus, proc)
            _, vt, _, wire = rec.operator_scenario(
                firmware, silence=lambda rows: firmware.silent.update(rows))
        finally:
            proc.terminate()
            _, err = proc.communicate(timeout=10)
            bus.shutdown()
    assert proc.returncode == 0, err.decode()
    return _log(wire), vt, err.decode()


@pytest.mark.slow
def test_in_lockstep_against_the_rigs_vt_the_c_firmware_gives_the_pythons_bus_log(
        isobus_bin: Path, python_run) -> None:
    """The operator's scenario (34 s of run time) with each implement: the same bus log,
    frame for frame and time for time (~6 s: the tractor's TC, the software bus's round
    trips). The firmware's meter feeds every row but the silent one: the firmware does not
    listen to the flow module of a row its TC switched off, as the Python does not."""
    py, py_events = python_run
    c, vt_c, stderr = _firmware_run(isobus_bin, ["vt=yes"])
    assert "VT client connected, 2 connection(s), 1 upload(s)" in stderr, stderr
    assert len(c) > 2000
    first = next((i for i, (a, b) in enumerate(zip(c, py, strict=False)) if a != b), None)
    assert first is None and len(c) == len(py), (
        f"first difference at frame {first}: C {c[first:first + 3] if first else c[-3:]}, "
        f"Python {py[first:first + 3] if first else py[-3:]}")
    # and the operator's path is in it: the pool active, the alarm on screen, the reload
    kinds = [(e.kind, e.detail) for e in vt_c.events]  # type: ignore[attr-defined]
    assert sum(k == "activated" for k, _ in kinds) == 2, kinds
    assert any(k == "activated" and "loaded version" in d for k, d in kinds), kinds
    assert any(cmd.function == 0xAD and cmd.object_id == IDS.alarm and cmd.error == 0
               for cmd in vt_c.commands)  # type: ignore[attr-defined]
    assert [(e.kind, e.time_s) for e in vt_c.events] == py_events  # type: ignore[attr-defined]


@pytest.mark.slow
def test_the_lockstep_comparison_fails_a_firmware_that_ignores_the_master_key(
        isobus_bin: Path, python_run) -> None:
    """The same comparison with the must-fail firmware (vt_defect=ignores-master): the logs
    part at Master off (20 s), not before."""
    py, _ = python_run
    c, _, _ = _firmware_run(isobus_bin, ["vt=yes", "vt_defect=ignores-master"])
    first = next((i for i, (a, b) in enumerate(zip(c, py, strict=False)) if a != b), None)
    assert first is not None
    assert 20.0 <= c[first][0] <= 20.5, (c[first], py[first])


# ------------------------------------------------------------------ on the rig
def _vt_firmware_profile(directory: Path) -> Path:
    """The C firmware's DUT profile with its operator interface: the ISOBUS firmware profile's
    with ``vt = "yes"`` (``dut_profiles/fertilizer-piecewise-pid-isobus-vt-firmware.toml``,
    checked here to differ from it in nothing else)."""
    path = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-isobus-vt-firmware.toml"
    base = (ROOT / "dut_profiles" / "fertilizer-piecewise-pid-isobus-firmware.toml").read_text()
    def strip(text: str) -> list[str]:
        return [line for line in text.splitlines()
                if line.strip() and not line.startswith("#")
                and not line.startswith(("name =", "controller =", "description =", "vt ="))]

    assert strip(path.read_text()) == strip(base)
    return path


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["isobus-vt-operator", "isobus-vt-restart"])
def test_on_the_rig_with_its_vt_the_c_firmware_gives_the_pythons_bus_log(
        isobus_bin: Path, tmp_path: Path, scenario: str) -> None:
    """The fertilizer rig's VT scenarios (the tractor's VT beside its TC, the operator's steps)
    in lockstep with the C firmware on the software bus and with the Python implement in
    process (its daemon profile, inline bus): the same bus.log, line for line (~20-60 s: the
    first builds the firmware through the profile)."""
    runs = {}
    for name, profile, bus in (
            ("c", _vt_firmware_profile(tmp_path), "softbus"),
            ("python", ROOT / "dut_profiles" / "fertilizer-piecewise-pid-isobus-vt-daemon.toml",
             "inline")):
        out = tmp_path / name
        done = subprocess.run([str(Path(sys.executable).with_name("hil")), "run", "--dut",
                               str(profile), "--scenario", scenario, "--bus", bus, "--out",
                               str(out)], capture_output=True, text=True, timeout=600, cwd=ROOT)
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
        runs[name] = (out / "bus.log").read_text().splitlines()
    c, python = runs["c"], runs["python"]
    from_dut = [line for line in c if line.split()[-1:] == ["R"]]
    assert len(from_dut) > 1000
    first = next((i for i, (a, b) in enumerate(zip(c, python, strict=False)) if a != b), None)
    assert first is None and len(c) == len(python), (
        f"first difference at bus.log line {first}: C {c[first:first + 2] if first else c[-2:]},"
        f" Python {python[first:first + 2] if first else python[-2:]}")


@pytest.mark.slow
@pytest.mark.realtime
def test_free_running_against_hil_isobus_serve_its_pool_goes_active_on_the_vt(
        isobus_bin: Path, tmp_path: Path) -> None:
    """The program free-running (its own 100 ms tick) against ``hil isobus serve --vt`` in real
    time (~15 s): the VT has its pool active and stored (1,047 bytes, AGF-VT1), and the program
    says its VT client is connected when it stops."""
    out = tmp_path / "serve"
    with SoftwareBus(port=0) as sb:
        firmware = subprocess.Popen([str(isobus_bin), "--bus", sb.spec(), "--period-ms", "100",
                                     "--param", "vt=yes"], stdin=subprocess.DEVNULL,
                                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            fields = ROOT / "plant_emulators" / "fertilizer" / "fields"
            serve = subprocess.run(
                [str(Path(sys.executable).with_name("hil")), "isobus", "serve", "--bus",
                 sb.spec(), "--path", str(fields / "field-rect.geojson"), "--map",
                 str(fields / "rates-3zones.geojson"), "--drive-after", "0.5", "--duration",
                 "15", "--out", str(out), "--quiet", "--vt"],
                capture_output=True, text=True, timeout=120)
        finally:
            firmware.terminate()
            _, err = firmware.communicate(timeout=10)
    assert serve.returncode == 0, serve.stderr[-2000:]
    assert firmware.returncode == 0, err.decode()
    assert "VT client connected, 1 connection(s), 1 upload(s)" in err.decode(), err.decode()
    record = json.loads((out / "vt" / "vt.json").read_text())
    (ws,) = record["working_sets"]
    assert ws["address"] == 0x81 and ws["pool_bytes"] == 1047 and ws["connected_at_end"]
    assert ws["version_label"] == "AGF-VT1"
    kinds = [e["kind"] for e in record["events"]]
    assert kinds.index("activated") < kinds.index("stored"), kinds
