"""The C firmware built against another database (the DepthPro DP-200 of docs/examples/byo-depth):
qualified with its binding, it controls as the reference does on agrihil's own database, to
the last digit in lockstep, and it remaps the servo drive's PDOs at boot by SDO.

``agrihil-depth-dp200-fw`` (firmware/byo/) packs and unpacks every frame with C code that
cantools generates from the DP-200's database (firmware/byo/generate.sh); the control core (fuzzy
PID, roller hold) is the reference firmware's. The rig speaks the DP-200's frames through
``depthpro_dp200.binding.toml``, and its servo drive takes the DP-200's PDO mapping. The
DP-200's scalings are exact multiples of the rig's resolutions, so every value reaches the law
as the same double.

The C build is held to the Python build of the same layout
(reference_controllers/sowing_depth/dbc_adapter.py) byte for byte by ctest
(firmware/byo/byo.cmake, ``dp200_vectors``); here: its vectors are what the Python build writes
today, the rig runs, and a drive that refuses the configuration, or does not answer, stops the
program with the object named.
"""

from __future__ import annotations

import dataclasses
import fcntl
import subprocess
import sys
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest

from hil.record import load_traces
from hil.rig.runner import RunOptions, run_scenario
from hil.rig.scenario import Event
from hil.softbus import SoftwareBus
from plant_emulators.sowing_depth.rig import SowingDepthRig
from tests.helpers.fresh_vectors import assert_vectors_fresh
from tests.helpers.same_measurements import qualified_measurements

ROOT = Path(__file__).resolve().parents[2]
HIL = str(Path(sys.executable).with_name("hil"))
EXAMPLE = ROOT / "docs" / "examples" / "byo-depth"
BINDING = EXAMPLE / "depthpro_dp200.binding.toml"
PROFILE = EXAMPLE / "depthpro-dp200-firmware.toml"
REFERENCE = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-daemon.toml"
VECTORS = ROOT / "firmware" / "byo" / "tests" / "data-dp200"
MAKE_VECTORS = ROOT / "firmware" / "byo" / "tests" / "make_vectors_dp200.py"
APP = "agrihil-depth-dp200-fw"
BOOTUP = 0x70A
PARAMS = ["--param", "kp0=3.0", "--param", "ki0=0.1", "--param", "kd0=0.0"]
DP200_RIG = {"wiring": {"binding_file": str(BINDING)}}
SYNC, NMT, SDO_REQUEST, SDO_RESPONSE, DRIVE_HEARTBEAT = 0x080, 0x000, 0x602, 0x582, 0x702


@pytest.fixture(scope="module")
def dp200_bin(firmware_bin: Path) -> Path:
    """The DP-200 program, built in the firmware tests' cached build directory."""
    app = firmware_bin / APP
    with (firmware_bin.parent / f"{firmware_bin.name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not app.exists():
            done = subprocess.run(["cmake", "--build", str(firmware_bin), "-j2", "--target", APP],
                                  capture_output=True, text=True, timeout=300)
            assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return app


def _scenario(duration_s: float = 6.0, *, faults: bool = True) -> Any:
    """The paths that matter: boot and the drive's configuration, a set-point step, a broken
    inclinometer wire (the roller hold), the controller's power cycle (test_depth_byo.py's)."""
    base = SowingDepthRig.load_scenario("depth-step")
    events = (Event(at_s=1.0, set={"target_depth_mm": 40.0}),)
    if faults:
        events += (Event(at_s=3.0, fault="inclinometer_open_circuit"),
                   Event(at_s=3.6, clear="inclinometer_open_circuit"),
                   Event(at_s=4.5, dut="restart"))
    return dataclasses.replace(base, duration_s=duration_s, events=events)


def _run(tmp: Path, dut: Any, rig: dict[str, Any], scenario: Any) -> dict[str, np.ndarray]:
    result = run_scenario(SowingDepthRig, scenario, dut,
                          RunOptions(out_dir=tmp, bus="softbus", clock="lockstep",
                                     rig_config=rig))
    assert result.record.get("error") in (None, ""), result.record.get("error")
    assert result.record["dut"]["exit_code"] == 0, result.record["dut"]
    return load_traces(tmp / "traces.npz")[0]


def _reference(tmp: Path, firmware_bin: Path, firmware_dut: Any,
               scenario: Any) -> dict[str, np.ndarray]:
    return _run(tmp / "own", firmware_dut([str(firmware_bin / "agrihil-depth-fw"), "--sync",
                                           *PARAMS], bootup_id=0x701), {}, scenario)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.array_equal(a, b, equal_nan=True))


def test_the_dp200_firmware_commands_what_the_reference_firmware_commands(
        tmp_path: Path, firmware_bin: Path, dp200_bin: Path, firmware_dut: Any) -> None:
    """Same seed, same scenario, both programs over the software bus in lockstep: every trace
    (rod, forces, depths, statusword) is identical, sample for sample, through the drive's
    configuration, a step, a sensor fault and a power cycle."""
    own = _reference(tmp_path, firmware_bin, firmware_dut, _scenario())
    theirs = _run(tmp_path / "dp200", firmware_dut([str(dp200_bin), "--sync", *PARAMS],
                                                   bootup_id=BOOTUP), DP200_RIG, _scenario())
    assert np.ptp(own["rod_position_mm"]) > 5.0                     # the rod was driven
    assert np.nanmax(own["sensed_depth_mm"]) > 35.0                 # and followed the step
    assert sorted(theirs) == sorted(own)
    for name in own:
        assert _same(theirs[name], own[name]), name


def test_a_wrong_binding_is_seen_by_the_comparison(tmp_path: Path, firmware_bin: Path,
                                                   dp200_bin: Path, firmware_dut: Any) -> None:
    """The comparison can fail: a binding that sends the inclinometer's "ok" as the hub's
    OpenCircuit passes `hil profile check`, and the DP-200 never regulates, so its rod differs
    from the reference's."""
    text = BINDING.read_text(encoding="utf-8")
    old = 'TiltXState", multiplexer = "Channel", rows = [0], values = { 0 = 1, 1 = 2,'
    assert old in text
    wrong = tmp_path / "wrong.binding.toml"
    wrong.write_text(text.replace(old, old.replace("0 = 1, 1 = 2", "0 = 2, 1 = 1"))
                     .replace('database = "depthpro_dp200.dbc"',
                              f'database = "{EXAMPLE / "depthpro_dp200.dbc"}"'),
                     encoding="utf-8")
    scenario = _scenario(3.0, faults=False)
    own = _reference(tmp_path, firmware_bin, firmware_dut, scenario)
    theirs = _run(tmp_path / "wrong", firmware_dut([str(dp200_bin), "--sync", *PARAMS],
                                                   bootup_id=BOOTUP),
                  {"wiring": {"binding_file": str(wrong)}}, scenario)
    assert np.ptp(own["rod_position_mm"]) > 5.0
    assert np.ptp(theirs["rod_position_mm"]) < 0.5


def _configuration(app: Any) -> list[can.Message]:
    """The drive boots; the 30 SDO writes the DP-200 sends in answer."""
    app.send(DRIVE_HEARTBEAT, b"\x00")
    requests: list[can.Message] = []
    while len(requests) < 30:
        msg = app.bus.recv(2.0)
        assert msg is not None, f"{len(requests)} SDO requests; stderr:\n{app.stderr()}"
        if msg.arbitration_id == SDO_REQUEST:
            requests.append(msg)
    return requests


def _answer(request: can.Message, command: int = 0x60, data: int = 0) -> bytes:
    return bytes([command]) + bytes(request.data[1:4]) + data.to_bytes(4, "little")


def test_a_refused_configuration_stops_the_firmware(start_app: Any) -> None:
    """The drive refuses 0x1600:02 (abort 0x06040041): the program does not start the drive,
    names the object, the code and its meaning, and exits 3."""
    with SoftwareBus(port=0) as sb:
        app = start_app(APP, sb.spec(), "--sync", *PARAMS, bootup_id=BOOTUP)
        requests = _configuration(app)
        assert requests[0].data[:4] == bytes([0x23, 0x00, 0x14, 0x01])  # RPDO1 invalid first
        assert requests[-1].data[:4] == bytes([0x2B, 0x17, 0x10, 0x00])  # heartbeat time last
        for request in requests[:8]:
            app.send(SDO_RESPONSE, _answer(request))
        assert bytes(requests[8].data[1:4]) == bytes([0x00, 0x16, 0x02])
        app.send(SDO_RESPONSE, _answer(requests[8], 0x80, 0x06040041))
        code = app.proc.wait(5)
        stderr = app.stderr()
        assert code == 3, stderr
        assert ("0x1600:02 = 0x60400010 refused (SDO abort 0x06040041: object cannot be "
                "mapped to the PDO)") in stderr
        while (msg := app.bus.recv(0.05)) is not None:
            assert msg.arbitration_id != NMT                          # the drive not started


def test_a_silent_drive_stops_the_firmware(start_app: Any) -> None:
    """No answer to the configuration within 0.5 s of steps: exit 3, the object named."""
    with SoftwareBus(port=0) as sb:
        app = start_app(APP, sb.spec(), "--sync", *PARAMS, bootup_id=BOOTUP)
        requests = _configuration(app)
        app.send(SDO_RESPONSE, _answer(requests[0]))
        for _ in range(60):
            app.send(SYNC)
            if app.proc.poll() is not None:
                break
        code = app.proc.wait(5)
        stderr = app.stderr()
        assert code == 3, stderr
        assert "0x1401:01 = 0x80000302: no answer from the drive (node 2) within 0.5 s" in stderr
        assert "1 of 30 writes confirmed" in stderr


def test_the_vectors_are_what_the_python_build_writes(tmp_path: Path) -> None:
    """ctest replays firmware/byo/tests/data-dp200 through the C build; they must be the Python
    build's frames of today, or the replay proves nothing about it."""
    assert_vectors_fresh(MAKE_VECTORS, VECTORS, tmp_path, root=ROOT, files=3)


def test_the_profile_checks() -> None:
    done = subprocess.run([HIL, "profile", "check", str(PROFILE)], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


@pytest.mark.slow
def test_the_dp200_firmware_qualifies_with_the_reference_measurements(tmp_path: Path) -> None:
    """``hil qualify``, fast and robustness suites, lockstep, seed 0: the DP-200 firmware over
    the software bus and the reference (the Python controller, on the inline bus) give every
    control measurement the same number (27 of 27 when written, ~5 min on a loaded host).

    The Python controller is the yardstick, as for every build of the depth law. (The
    reference C firmware gave 0.031 mm on ``depth.fault.speed_loss.rod_travel`` against
    7.6e-10 mm until apps/depth_adapter.c read the GNSS speed at the start of a step, as the
    Python builds and this one do; it now gives the same.)"""
    records = {name: qualified_measurements(HIL, profile, tmp_path / name, bus=bus,
                                            prefix="depth.", cwd=ROOT)
               for name, profile, bus in (("ref", REFERENCE, "inline"),
                                          ("dp200", PROFILE, "softbus"))}
    assert len(records["ref"]) > 20
    assert ("depth.fault.speed_loss.rod_travel", "{}") in records["ref"]
    assert records["dp200"] == records["ref"]
