"""Whole fertilizer runs give the same bytes on both physics engines.

The C twins of the rig's models (``plant_emulators.engine``) are checked model by model in
``tests/plant_emulators/fertilizer/test_*_native.py``; here whole scenarios run once per
engine, against the in-process reference controller, and everything the run leaves behind is
compared: the candump and ASC bus logs byte for byte, every trace, the truth. The record says
which engine ran.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hil.dut import InProcessDut
from hil.rig import RunOptions, run_scenario
from plant_emulators.engine import ENV_VAR
from plant_emulators.fertilizer.controllers import PiFlowController
from plant_emulators.fertilizer.rig import FertilizerRig

pytest.importorskip("plant_emulators.fertilizer._plant_native",
                    reason="the C twins are not built (scripts/setup.sh builds them)")


def _run(tmp: Path, scenario: str, engine: str, monkeypatch: pytest.MonkeyPatch
         ) -> dict[str, object]:
    monkeypatch.setenv(ENV_VAR, engine)
    out = tmp / engine
    run = run_scenario(FertilizerRig, FertilizerRig.load_scenario(scenario),
                       InProcessDut(PiFlowController()), RunOptions(out_dir=out, bus="inline"))
    assert run.record["error"] is None
    return run.record


def _asc_frames(path: Path) -> list[str]:
    """The ASC log without its header lines, which carry the wall-clock date."""
    return [line for line in path.read_text().splitlines()
            if not line.startswith(("date ", "Begin Triggerblock"))]


@pytest.mark.parametrize("scenario", ["field-stop-go", "fault-motor-stall",
                                      "fault-sensor-garbage"])
def test_both_engines_leave_the_same_run(tmp_path: Path, scenario: str,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    records = {e: _run(tmp_path, scenario, e, monkeypatch) for e in ("python", "native")}
    for engine, record in records.items():
        assert set(record["physics_engines"].values()) == {engine}
    py, nat = tmp_path / "python", tmp_path / "native"
    assert (py / "bus.log").read_bytes() == (nat / "bus.log").read_bytes()
    assert _asc_frames(py / "bus.asc") == _asc_frames(nat / "bus.asc")
    with np.load(py / "traces.npz") as a, np.load(nat / "traces.npz") as b:
        assert sorted(a.files) == sorted(b.files)
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    assert json.dumps(records["python"]["truth"]) == \
        json.dumps(records["native"]["truth"])
    assert (py / "bus.log").stat().st_size > 10_000    # a real run, not an empty one
