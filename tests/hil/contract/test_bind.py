"""``hil profile bind``: a starting binding from a database, TODO where undecided."""

from __future__ import annotations

import tomllib
from pathlib import Path

from hil.contract.bind import write_binding
from hil.contract.binding import load_binding
from hil.contract.quantity import Contract
from hil.contract.registry import rig_contract
from tests.fuzz.cli import run_cli
from tests.hil.contract.conftest import ACME_DBC

ROOT = Path(__file__).resolve().parents[3]


def test_binding_the_rig_s_own_dbc_rebuilds_its_default_binding(fert: Contract,
                                                                tmp_path: Path) -> None:
    out = tmp_path / "mine.binding.toml"
    outcome = run_cli("profile", "bind", str(ROOT / "plant_emulators/fertilizer/db/"
                                              "fertilizer.dbc"), "--rig", "fertilizer",
                      "-o", str(out))
    assert outcome.code == 0, outcome.stderr
    assert load_binding(out).carriers == load_binding(fert.default_binding_file).carriers


def test_the_depth_rig_s_dbc_too(tmp_path: Path) -> None:
    depth = rig_contract("sowing-depth")
    text = write_binding(ROOT / "plant_emulators/sowing_depth/db/sowing_depth.dbc", depth,
                         relative_to=tmp_path)
    (tmp_path / "b.toml").write_text(text)
    mine = load_binding(tmp_path / "b.toml").carriers
    default = load_binding(depth.default_binding_file).carriers
    right = [name for name in default if mine.get(name) == default[name]]
    assert len(right) >= len(default) - 4, sorted(set(default) - set(right))


def test_a_foreign_database_gets_its_layout_and_todos(fert: Contract) -> None:
    text = write_binding(ACME_DBC, fert)
    data = tomllib.loads(text)
    q = data["quantities"]
    assert data["dut_node"] == "AcmeCtl"
    assert q["target_flow"] == {"message": "AcmeSetpoint", "signal": "FlowKgH"}
    assert q["row_flow"] == {"message": "AcmeRowFlow", "signal": "Flow_R{row}",
                             "multiplexer": "RowIdx", "rows": [1, 2, 3, 4]}
    assert q["motor_command"] == {"message": "ValveCmd", "signal": "MotorMv"}
    assert "mode" not in q                       # "Program": nothing in its name says mode
    assert "# TODO (required): mode = " in text
    assert "TODO: confirm the multiplexer value of each row" in text


def test_an_unreadable_database_is_a_named_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.dbc"
    bad.write_text("BO_ nonsense\n")
    outcome = run_cli("profile", "bind", str(bad))
    assert outcome.code == 2 and "bad.dbc" in outcome.stderr
    assert "Traceback" not in outcome.stderr
    outcome = run_cli("profile", "bind", str(tmp_path / "none.dbc"))
    assert outcome.code == 2 and "none.dbc" in outcome.stderr
