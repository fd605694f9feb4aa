"""The signal-level depth FMU (firmware/fmu/depth_signal, FMI 2.0) does, value for value, what
the depth firmware does on the bus.

The depth firmware's LS-BUS FMU runs a scenario on the inline bus (its bus log is the
firmware's, byte for byte: test_reference_fmus.py); the log is then replayed into the
signal-level FMU as a signal-level importer hands it values: at each SYNC, the latest value of
every quantity the rig sent since (the drive's NMT state, statusword and position, the
set-point, the tractor's speed and distance, the inclinometer's X voltage, status and counter),
one ``doStep`` per control period. Each step's outputs must be what the firmware sent after
that SYNC: the controlword and target velocity (RPDO2) every step, the status frame's values
every tenth, the mode of operation (RPDO3) from the step it was written, the NMT start where
it went out.

Not covered here: running it as a DUT. The sowing-depth rig's bus contract carries no quantity
for the servo drive's CiA 402 objects (its PDOs are the drive's EDS's, not the rig's database),
so no profile can bind the FMU's ``Drive_*`` variables yet (docs/guide/fmu-controller.md).
"""

from __future__ import annotations

import dataclasses
import fcntl
import hashlib
import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

import cantools
import pytest

from hil.dut.factory import make_dut, profile_run_options
from hil.dut.profile import load_profile
from hil.rig.runner import RunOptions, run_scenario
from plant_emulators.sowing_depth.rig import SowingDepthRig

ROOT = Path(__file__).resolve().parents[3]
FIRMWARE = ROOT / "firmware"
LSBUS = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-fmu-lsbus.toml"
DB = cantools.database.load_file(ROOT / "plant_emulators/sowing_depth/db/sowing_depth.dbc")
SOURCES = ("fmu", "core", "apps", "generated", "hal")
TARGET = "agrihil-depth-signal"
PERIOD_S = 0.01
#: the contract's gains, as the profiles pin them
GAINS = {"kp0": 3.0, "ki0": 0.1, "kd0": 0.0}

INCLINOMETER, GBSD, SETPOINT, STATUS = 0x0CFF11A1, 0x0CFE49F0, 0x18FF2026, 0x18FF3080
SYNC, NMT, DRIVE_HEARTBEAT, TPDO1, RPDO2, RPDO3 = 0x080, 0x000, 0x702, 0x182, 0x302, 0x402


def _source_hash() -> str:
    digest = hashlib.sha256()
    for top in SOURCES:
        for path in sorted((FIRMWARE / top).rglob("*")):
            if path.is_file():
                digest.update(str(path.relative_to(FIRMWARE)).encode())
                digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _cache_root() -> Path:
    explicit = os.environ.get("AGRIHIL_CACHE")
    if explicit:
        return Path(explicit)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "agrihil"


@pytest.fixture(scope="module")
def signal_fmu() -> Path:
    """The signal-level depth FMU, built once per source tree into agrihil's build cache."""
    if shutil.which("cmake") is None or shutil.which("cc") is None:
        pytest.skip("cmake and a C compiler are needed to build the FMU")
    build = _cache_root() / "builds" / f"fmu-depth-signal-{_source_hash()}"
    build.mkdir(parents=True, exist_ok=True)
    with (build / ".lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (build / ".built").exists():
            for cmd in (["cmake", "-S", str(FIRMWARE / "fmu"), "-B", str(build),
                         "-DCMAKE_BUILD_TYPE=Release"],
                        ["cmake", "--build", str(build), "-j2", "--target", TARGET]):
                done = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
                assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
            (build / ".built").write_text("ok\n")
    return build / "fmus" / f"{TARGET}.fmu"


def firmware_log(tmp: Path, scenario: str, seconds: float) -> list[tuple[int, bool, bytes]]:
    """The depth firmware's bus log (as its LS-BUS FMU on the inline bus): (id, from the
    DUT, data) per frame, in bus order."""
    profile = load_profile(LSBUS)
    dut, _ = make_dut(profile, bus="inline", clock="lockstep", log_dir=tmp)
    sc = dataclasses.replace(SowingDepthRig.load_scenario(scenario), duration_s=seconds)
    result = run_scenario(SowingDepthRig, sc, dut,
                          RunOptions(out_dir=tmp, bus="inline", clock="lockstep",
                                     **profile_run_options(profile)))
    assert result.record.get("error") in (None, ""), result.record.get("error")
    out = []
    for line in (tmp / "bus.log").read_text().splitlines():
        _, _, frame, direction = line.split()
        can_id, _, data = frame.partition("#")
        out.append((int(can_id, 16), direction == "R", bytes.fromhex(data)))
    return out


class SignalFmu:
    """The FMU through fmpy's FMI 2.0 co-simulation API, its variables by name."""

    def __init__(self, path: Path, tmp: Path) -> None:
        from fmpy import extract, read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.md = read_model_description(str(path))
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=extract(str(path), str(tmp)),
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName="depth-signal")
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for name, value in GAINS.items():
            self.set(name, value)
        self.fmu.exitInitializationMode()

    def set(self, name: str, value: Any) -> None:
        var = self.vars[name]
        if var.type == "Real":
            self.fmu.setReal([var.valueReference], [float(value)])
        else:
            self.fmu.setInteger([var.valueReference], [int(value)])

    def get(self, name: str) -> Any:
        var = self.vars[name]
        getter = {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger,
                  "Boolean": self.fmu.getBoolean}[var.type]
        return getter([var.valueReference])[0]

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


def inputs_of(can_id: int, data: bytes) -> dict[str, Any]:
    """What a signal-level importer would hand the FMU of one rig frame."""
    if can_id == DRIVE_HEARTBEAT:
        return {"Drive_NmtState": data[0] & 0x7F}
    if can_id == TPDO1:
        return {"Drive_Statusword": int.from_bytes(data[0:2], "little"),
                "Drive_Position": int.from_bytes(data[2:6], "little", signed=True) / 100.0}
    if can_id == INCLINOMETER:
        m = DB.decode_message(can_id, data, decode_choices=False)
        return {"InclinometerX": m["INC_X_Voltage"], "InclinometerXStatus": m["INC_X_Status"],
                "InclinometerCounter": m["INC_Counter"]}
    if can_id == GBSD:
        m = DB.decode_message(can_id, data, decode_choices=False)
        return {"GroundSpeed": m["GBSD_GroundSpeed"],
                "GroundDistance": m["GBSD_GroundDistance"]}
    if can_id == SETPOINT:
        m = DB.decode_message(can_id, data, decode_choices=False)
        return {"Setpoint_TargetDepth": m["DS_TargetDepth"], "Setpoint_Enable": m["DS_Enable"],
                "Setpoint_Mode": m["DS_Mode"], "Setpoint_Counter": m["DS_Counter"]}
    return {}


STATUS_OUTPUTS = {"DC_MeasuredDepth": "Status_MeasuredDepth",
                  "DC_RollerPositionCommand": "Status_RollerPositionCommand",
                  "DC_State": "Status_State", "DC_SensorFault": "Status_SensorFault",
                  "DC_DriveFault": "Status_DriveFault", "DC_SpeedLost": "Status_SpeedLost",
                  "DC_Counter": "Status_Counter"}


def expected_of(frames: list[tuple[int, bytes]]) -> dict[str, Any]:
    """What the firmware sent after one SYNC, as the FMU's outputs name it."""
    out: dict[str, Any] = {"Drive_NmtCommand": 0}
    for can_id, data in frames:
        if can_id == NMT:
            out["Drive_NmtCommand"] = data[0]
        elif can_id == RPDO2:
            out["Drive_Controlword"] = int.from_bytes(data[0:2], "little")
            out["Drive_TargetVelocity"] = int.from_bytes(data[2:6], "little", signed=True)
        elif can_id == RPDO3:
            out["Drive_ModeOfOperation"] = int.from_bytes(data[0:1], "little", signed=True)
        elif can_id == STATUS:
            m = DB.decode_message(can_id, data, decode_choices=False)
            out.update({STATUS_OUTPUTS[k]: v for k, v in m.items()})
    return out


def replay(fmu: SignalFmu, log: list[tuple[int, bool, bytes]]) -> tuple[int, list[str]]:
    """Step the FMU through the log; the number of steps and every difference found."""
    latest: dict[str, Any] = {}
    # the DUT's frames after each SYNC (the boot-up before the first is the harness's)
    steps: list[tuple[dict[str, Any], list[tuple[int, bytes]]]] = []
    for can_id, from_dut, data in log:
        if from_dut:
            if steps:
                steps[-1][1].append((can_id, data))
        elif can_id == SYNC:
            steps.append((dict(latest), []))
        else:
            latest.update(inputs_of(can_id, data))
    differences: list[str] = []
    mode = 0
    for k, (values, sent) in enumerate(steps):
        for name, value in values.items():
            fmu.set(name, value)
        fmu.fmu.doStep(currentCommunicationPoint=k * PERIOD_S, communicationStepSize=PERIOD_S)
        want = expected_of(sent)
        mode = want.get("Drive_ModeOfOperation", mode)
        want["Drive_ModeOfOperation"] = mode
        for name, value in want.items():
            got = fmu.get(name)
            if name == "Drive_TargetVelocity":
                got = round(got * 100.0)
            # a float is a scaled raw value: equal to far below its resolution
            same = (abs(got - value) < 1e-9 if isinstance(value, float)
                    else int(got) == int(value))
            if not same:
                differences.append(f"step {k} ({k * PERIOD_S:.2f} s) {name}: FMU {got}, "
                                   f"firmware {value}")
    return len(steps), differences


@pytest.mark.slow
@pytest.mark.parametrize("scenario, seconds", [
    ("depth-step", 30.0),              # the drive's start, set-point steps
    ("stop-go", 30.0),                 # the tractor stops and goes on: control off and on
    ("fault-drive-overcurrent", 30.0),  # the drive trips: fault reset, re-enable
    ("fault-inclinometer-stuck", 30.0),  # a frozen X voltage: the roller held
])
def test_the_depth_signal_fmu_commands_what_the_firmware_commands(
        tmp_path: Path, signal_fmu: Path, scenario: str, seconds: float) -> None:
    log = firmware_log(tmp_path / "run", scenario, seconds)
    fmu = SignalFmu(signal_fmu, tmp_path / "fmu")
    try:
        n, differences = replay(fmu, log)
    finally:
        fmu.close()
    assert n == round(seconds / PERIOD_S) + 1
    assert differences == [], differences[:10]


@pytest.mark.slow
def test_the_replay_sees_a_different_controller(tmp_path: Path, signal_fmu: Path) -> None:
    """The comparison can fail: the FMU with ten times the proportional preset commands other
    velocities from the same inputs."""
    log = firmware_log(tmp_path / "run", "depth-step", 5.0)
    GAINS["kp0"] = 30.0
    try:
        fmu = SignalFmu(signal_fmu, tmp_path / "fmu")
    finally:
        GAINS["kp0"] = 3.0
    try:
        _, differences = replay(fmu, log)
    finally:
        fmu.close()
    assert any("Drive_TargetVelocity" in d for d in differences)
