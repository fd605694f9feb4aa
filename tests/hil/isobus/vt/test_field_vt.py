"""The VT in the rig's field runs: a scenario's ``[[operator]]`` list, the VT beside the TC
(:class:`hil.isobus.vt.fieldvt.FieldVt`), the setup error of a step the implement's pool lacks,
the run's VT record, and lockstep runs that repeat byte for byte."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import pytest

from hil.errors import ConfigError
from hil.isobus.field import load_field, load_prescription
from hil.isobus.tractor import Tractor, TractorSetup
from hil.isobus.vt.fieldvt import FieldVt, alarm_masks
from hil.isobus.vt.steps import OperatorStep
from hil.isobus.wire import VirtualWire
from hil.rig.scenario import load_scenario
from reference_controllers.fertilizer.isobus_vt import IsobusVtFlowController
from reference_controllers.fertilizer.operator_pool import IDS
from tests.helpers.hil_forkserver import HilForkServer
from tests.hil.isobus.vt.test_reference_vt import Node

ROOT = Path(__file__).resolve().parents[4]
SCENARIOS = ROOT / "plant_emulators" / "fertilizer" / "scenarios"
FIELDS = ROOT / "plant_emulators" / "fertilizer" / "fields"
VT_REFERENCE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-isobus-vt-daemon.toml"

SCENARIO_HEAD = f"""
name = "vt-steps"
description = "operator steps"
rig = "fertilizer"
duration_s = 10.0
[tractor]
field = "{FIELDS / 'field-rect.geojson'}"
drive_after_s = 4.0
"""


def _scenario(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO_HEAD + text)
    return path


# --------------------------------------------------------------------- the [[operator]] list
def test_the_operator_steps_go_with_the_tractors_vt() -> None:
    scenario = load_scenario(SCENARIOS / "isobus-vt-operator.toml")
    assert scenario.tractor is not None and scenario.tractor.vt
    assert [s.at_s for s in scenario.operator] == [11.0, 21.0, 24.0]
    assert scenario.tractor.operator == scenario.operator
    assert scenario.operator[1].acknowledge is True


def test_operator_steps_without_the_vt_are_refused(tmp_path: Path) -> None:
    path = _scenario(tmp_path, '[[operator]]\nat_s = 5.0\npress = "Master"\n')
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    assert "[operator]" in str(err.value) and "vt = true" in str(err.value)
    assert str(path) in str(err.value)


def test_a_step_after_the_end_of_the_run_is_refused(tmp_path: Path) -> None:
    path = _scenario(tmp_path, 'vt = true\n[[operator]]\nat_s = 5.0\npress = "Master"\n'
                               '[[operator]]\nat_s = 12.0\npress = "Master"\n')
    with pytest.raises(ConfigError, match=r"operator\[1\]\.at_s.*after the end"):
        load_scenario(path)


def test_a_step_with_two_actions_names_its_index(tmp_path: Path) -> None:
    path = _scenario(tmp_path, 'vt = true\n[[operator]]\nat_s = 5.0\npress = "Master"\n'
                               '[[operator]]\nat_s = 6.0\npress = "Master"\nescape = true\n')
    with pytest.raises(ConfigError, match=r"operator\[1\].*exactly one of"):
        load_scenario(path)


# --------------------------------------------------------------------- on the tractor
def _tractor_with_vt(steps: list[OperatorStep], defect: str = ""
                     ) -> tuple[Tractor, FieldVt, Node, VirtualWire]:
    fld = load_field(FIELDS / "field-rect.geojson")
    rx = load_prescription(FIELDS / "rates-3zones.geojson", frame=fld.frame)
    tractor = Tractor(TractorSetup(fld, rx, drive_after_s=3.0))
    field_vt = FieldVt(tractor.network, steps)
    node = Node(IsobusVtFlowController("physical", {"vt_defect": defect} if defect else {}))
    return tractor, field_vt, node, VirtualWire([tractor.network, node])


def test_a_step_naming_an_object_the_pool_lacks_is_a_setup_error_naming_it() -> None:
    steps = [OperatorStep(at_s=6.0, press="Master"), OperatorStep(at_s=7.0, press="Stop")]
    _, field_vt, _, wire = _tractor_with_vt(steps)
    wire.run_until(5.0)
    problem = field_vt.problem
    assert problem is not None
    text = str(problem)
    assert "[operator[1]]" in text and "'Stop'" in text and "'Master'" in text
    with pytest.raises(ConfigError):
        field_vt.raise_problem()


def test_the_operator_the_vt_and_its_record() -> None:
    """Master on, a lost row's alarm acknowledged, the VT down and back (the later steps
    played again), Master off: what the record says of it."""
    steps = [OperatorStep(at_s=5.0, press="Master"), OperatorStep(at_s=14.0, acknowledge=True),
             OperatorStep(at_s=12.5, press="Calib."), OperatorStep(at_s=22.0, press="Master")]
    _, field_vt, node, wire = _tractor_with_vt(steps)
    wire.run_until(8.0)
    node.silent = {2}
    wire.run_until(15.0)
    field_vt.set_down(True, 15.0)
    wire.run_until(19.0)
    field_vt.set_down(False, 19.0)
    wire.run_until(24.0)
    assert field_vt.problem is None
    record = json.loads(json.dumps(field_vt.record()))
    alarms = alarm_masks(record)
    assert [mask for _, mask in alarms] == [IDS.alarm]
    assert 8.0 + 2.5 + 1.0 <= alarms[0][0] <= 8.0 + 4.0
    # Calib. at 12.5 s was pressed while the alarm was shown: not on the screen, not done
    assert any("Calib." in m["why"] for m in record["operator_missed"])
    assert record["vt_down"] == [[15.0, 19.0]]
    active = [ws for ws in record["working_sets"] if ws["activated_s"] > 19.0]
    assert active and active[0]["loaded_from_storage"]
    # Master off after the VT came back: played again, and the implement stopped metering
    assert not node.ctl.master_on
    assert record["screens"] and set(record["screen_images"]) == {
        s["file"] for s in record["screens"]}
    shown = [m["type"] for m in record["masks"]]
    assert "none" in shown and shown[-1] == "data_mask"
    assert all(math.isfinite(float(m["t"])) for m in record["masks"])


# --------------------------------------------------------------------- hil run
@pytest.mark.slow
def test_hil_run_refuses_a_step_the_pool_lacks_with_exit_2(tmp_path: Path,
                                                            hil_forked: HilForkServer) -> None:
    text = (SCENARIOS / "isobus-vt-operator.toml").read_text().replace(
        'at_s = 24.0\npress = "Master"', 'at_s = 24.0\npress = "Stop"')
    text = text.replace('"../fields/', f'"{FIELDS}/')
    scenario = tmp_path / "bad-step.toml"
    scenario.write_text(text)
    out = tmp_path / "run"
    proc = hil_forked.run(["run", "--dut", str(VT_REFERENCE), "--scenario", str(scenario),
                           "--bus", "inline", "--out", str(out)], ROOT, timeout_s=300)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "operator[2]" in proc.stderr and "'Stop'" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.slow
def test_two_lockstep_runs_of_the_vt_scenario_give_identical_bus_logs(
        tmp_path: Path, hil_forked: HilForkServer) -> None:
    logs = []
    for i in range(2):
        out = tmp_path / f"run{i}"
        proc = hil_forked.run(["run", "--dut", str(VT_REFERENCE), "--scenario",
                               "isobus-vt-operator", "--bus", "inline", "--out", str(out)],
                              ROOT, timeout_s=300)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        logs.append((out / "bus.log").read_bytes())
    assert len(logs[0]) > 100_000 and logs[0] == logs[1]


def test_vt_down_needs_the_tractors_vt() -> None:
    from plant_emulators.fertilizer.field_run import FIELD_FAULTS, BoomGeometry, FieldRun
    from plant_emulators.fertilizer.rig import FertilizerRig

    assert "vt_down" in FIELD_FAULTS and "vt_down" in FertilizerRig.faults
    scenario = load_scenario(SCENARIOS / "isobus-tc-restart.toml")
    assert scenario.tractor is not None
    tractor = replace(scenario.tractor, vt=False, operator=())   # a tractor without a VT
    run = FieldRun(tractor, BoomGeometry(3.0, 4, -1.0))
    assert run.vt is None and "vt" not in run.truth()
    with pytest.raises(ConfigError, match=r"vt = true"):
        run.set_fault("vt_down", True, 1.0)


def test_screens_are_stored_pixel_for_pixel() -> None:
    """png_bytes: an indexed PNG for a screen of 256 colours or fewer, RGB beyond; the same
    pixels either way."""
    import io

    import numpy as np
    from PIL import Image

    from hil.isobus.vt.screens import png_bytes

    rng = np.random.default_rng(1)
    few = rng.integers(0, 256, (40, 3), dtype=np.uint8)[rng.integers(0, 40, (60, 80))]
    many = rng.integers(0, 256, (60, 80, 3), dtype=np.uint8)
    for pixels, mode in ((few, "P"), (many, "RGB")):
        image = Image.fromarray(pixels, "RGB")
        back = Image.open(io.BytesIO(png_bytes(image)))
        assert back.mode == mode
        assert back.convert("RGB").tobytes() == image.tobytes()
