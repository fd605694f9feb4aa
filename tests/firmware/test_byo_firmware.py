"""The C firmware built against another database (the RateMaster RC-400 of
docs/examples/byo-fertilizer): qualified with its binding, it controls as the reference C firmware
does on agrihil's own database, to the last digit in lockstep.

``agrihil-fertilizer-rc400-fw`` (firmware/byo/) packs and unpacks every frame with C code that
cantools generates from the RC-400's database (firmware/byo/generate.sh); the control core and
the app loop are the reference firmware's. The rig speaks the RC-400's frames through
``ratemaster_rc400.binding.toml``. The RC-400's scalings are exact multiples of the rig's
resolutions, so the same raw numbers cross the bus and the same millivolts come back.

The C build is held to the Python build of the same layout
(reference_controllers/fertilizer/dbc_adapter.py) byte for byte by ctest (firmware/byo/byo.cmake,
``rc400_vectors``); here: its vectors are what the Python build writes today, and the rig runs.
"""

from __future__ import annotations

import dataclasses
import fcntl
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hil.record import load_traces
from hil.rig.runner import RunOptions, run_scenario
from plant_emulators.fertilizer.rig import FertilizerRig
from tests.helpers.fresh_vectors import assert_vectors_fresh
from tests.helpers.same_measurements import qualified_measurements

ROOT = Path(__file__).resolve().parents[2]
HIL = str(Path(sys.executable).with_name("hil"))
EXAMPLE = ROOT / "docs" / "examples" / "byo-fertilizer"
BINDING = EXAMPLE / "ratemaster_rc400.binding.toml"
PROFILE = EXAMPLE / "ratemaster-rc400-firmware.toml"
REFERENCE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-firmware.toml"
GENERATED = ROOT / "firmware" / "byo" / "generated"
VECTORS = ROOT / "firmware" / "byo" / "tests" / "data"
MAKE_VECTORS = ROOT / "firmware" / "byo" / "tests" / "make_vectors.py"
APP = "agrihil-fertilizer-rc400-fw"
PARAMS = ["--param", "mode=physical", "--param", "ff_coeff=4.39"]
SLIDING: dict[str, Any] = {"flow_sensor": {"mode": "sliding"}}
RC400_RIG = {**SLIDING, "wiring": {"binding_file": str(BINDING), "dut_node_id": 0x12}}


@pytest.fixture(scope="module")
def rc400_bin(firmware_bin: Path) -> Path:
    """The RC-400 program, built in the firmware tests' cached build directory."""
    app = firmware_bin / APP
    with (firmware_bin.parent / f"{firmware_bin.name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not app.exists():
            done = subprocess.run(["cmake", "--build", str(firmware_bin), "-j2", "--target", APP],
                                  capture_output=True, text=True, timeout=300)
            assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return app


def _run(tmp: Path, dut: Any, rig: dict[str, Any], scenario: str,
         duration_s: float) -> dict[str, np.ndarray]:
    sc = dataclasses.replace(FertilizerRig.load_scenario(scenario), duration_s=duration_s)
    result = run_scenario(FertilizerRig, sc, dut,
                          RunOptions(out_dir=tmp, bus="softbus", clock="lockstep",
                                     rig_config=rig))
    assert result.record.get("error") in (None, ""), result.record.get("error")
    assert result.record["dut"]["exit_code"] == 0, result.record["dut"]
    return load_traces(tmp / "traces.npz")[0]


def _compare(tmp: Path, firmware_bin: Path, rc400_bin: Path, firmware_dut: Any, scenario: str,
             duration_s: float, binding: Path = BINDING
             ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    own = _run(tmp / "own", firmware_dut([str(firmware_bin / "agrihil-fertilizer-fw"), "--sync",
                                          *PARAMS], bootup_id=0x710),
               SLIDING, scenario, duration_s)
    rig = {**RC400_RIG, "wiring": {**RC400_RIG["wiring"], "binding_file": str(binding)}}
    theirs = _run(tmp / "rc400", firmware_dut([str(rc400_bin), "--sync", *PARAMS],
                                              bootup_id=0x712),
                  rig, scenario, duration_s)
    return own, theirs


@pytest.mark.parametrize(("scenario", "duration_s"), [("bench-step-23", 6.0),
                                                      ("field-6kmh", 5.0)])
def test_the_rc400_firmware_commands_what_the_reference_firmware_commands(
        tmp_path: Path, firmware_bin: Path, rc400_bin: Path, firmware_dut: Any, scenario: str,
        duration_s: float) -> None:
    """Same seed, same scenario, both programs over the software bus in lockstep: every trace
    (commands, motor, flows, sensed flows, masses, speeds) is identical, sample for sample."""
    own, theirs = _compare(tmp_path, firmware_bin, rc400_bin, firmware_dut, scenario,
                           duration_s)
    assert np.max(own["command_v"]) > 1.0                 # the motor was driven
    assert np.nanmax(own["sensed_flow_1_gps"]) > 1.0       # and the rows reported
    assert sorted(theirs) == sorted(own)
    for name in own:
        np.testing.assert_array_equal(theirs[name], own[name], err_msg=name)


def test_a_wrong_binding_is_seen_by_the_comparison(tmp_path: Path, firmware_bin: Path,
                                                   rc400_bin: Path, firmware_dut: Any) -> None:
    """The comparison can fail: a binding that sends bench flow as the RC-400's fixed-speed
    program makes the firmware run the open-loop law, and the commands differ."""
    wrong = tmp_path / "wrong.binding.toml"
    wrong.write_text(BINDING.read_text(encoding="utf-8")
                     .replace("values = { 0 = 1, 1 = 2, 2 = 3 } }\nenable",
                              "values = { 0 = 1, 1 = 3, 2 = 2 } }\nenable")
                     .replace('database = "ratemaster_rc400.dbc"',
                              f'database = "{EXAMPLE / "ratemaster_rc400.dbc"}"'),
                     encoding="utf-8")
    own, theirs = _compare(tmp_path, firmware_bin, rc400_bin, firmware_dut, "bench-step-23",
                           6.0, wrong)
    assert np.max(theirs["command_v"]) > 1.0
    assert not np.array_equal(theirs["command_v"], own["command_v"])


def test_the_vectors_are_what_the_python_build_writes(tmp_path: Path) -> None:
    """ctest replays firmware/byo/tests/data through the C build; they must be the Python
    build's frames of today, or the replay proves nothing about it."""
    assert_vectors_fresh(MAKE_VECTORS, VECTORS, tmp_path, root=ROOT, files=3)


def test_the_bus_layer_is_generated_from_the_database(tmp_path: Path) -> None:
    """The committed C bus layers are what cantools generates from the RC-400's and the
    DP-200's databases today (``generate.sh`` writes both): the C builds speak the layouts the
    rig is bound to, not stale copies of them."""
    subprocess.run(["sh", str(ROOT / "firmware" / "byo" / "generate.sh"), str(tmp_path)],
                   check=True, capture_output=True, env={**os.environ, "PYTHON": sys.executable})
    for name in ("ratemaster_rc400.c", "ratemaster_rc400.h", "depthpro_dp200.c",
                 "depthpro_dp200.h"):
        assert (tmp_path / name).read_bytes() == (GENERATED / name).read_bytes(), \
            f"{name} is stale: rerun firmware/byo/generate.sh"


def test_the_profile_checks() -> None:
    done = subprocess.run([HIL, "profile", "check", str(PROFILE)], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


@pytest.mark.slow
def test_the_rc400_firmware_qualifies_with_the_reference_measurements(tmp_path: Path) -> None:
    """``hil qualify`` of both firmware profiles, fast and robustness suites, lockstep over the
    software bus, seed 0: every control measurement is the same number (~90 s; 32 of 32 when
    written, the accuracy gain against the open-loop baseline included)."""
    records = {name: qualified_measurements(HIL, profile, tmp_path / name, bus="softbus",
                                            prefix="flow.", cwd=ROOT)
               for name, profile in (("ref", REFERENCE), ("rc400", PROFILE))}
    assert len(records["ref"]) > 30
    assert ("flow.silence.recovery_time", "{}") in records["ref"]
    assert records["rc400"] == records["ref"]
