"""``hil profile check`` on bindings: the must-fail set (each refused with file, key, numbers
and fix, all at once, exit 2), the shipped profiles and a correct foreign binding pass."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from hil.contract.binding import load_binding
from hil.contract.checks import check_binding
from hil.contract.codec import ContractCodec
from hil.contract.quantity import Contract
from hil.errors import ConfigError
from plant_emulators.fertilizer.config import load_rig_config
from tests.fuzz.cli import run_cli
from tests.hil.contract.conftest import ACME_BINDING, ACME_DBC

ROOT = Path(__file__).resolve().parents[3]
DAEMON = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
RIG_DBC = ROOT / "plant_emulators" / "fertilizer" / "db" / "fertilizer.dbc"


def _acme(tmp_path: Path, *, dbc: tuple[str, str] | None = None,
          binding: tuple[str, str] | None = None) -> Path:
    """A copy of the acme database and binding with one edit each; the binding's path."""
    text = ACME_DBC.read_text()
    if dbc:
        assert dbc[0] in text, dbc
        text = text.replace(*dbc)
    (tmp_path / ACME_DBC.name).write_text(text)
    text = ACME_BINDING.read_text()
    if binding:
        assert binding[0] in text, binding
        text = text.replace(*binding)
    path = tmp_path / ACME_BINDING.name
    path.write_text(text)
    return path


def _errors(fert: Contract, path: Path) -> list[str]:
    return [str(p) for p in check_binding(fert, load_binding(path)) if not p.note]


def test_the_foreign_binding_passes(fert: Contract, tmp_path: Path) -> None:
    assert _errors(fert, _acme(tmp_path)) == []


#: (what is wrong, database edit, binding edit, words of the error)
MUST_FAIL = [
    ("wrong scaling", None,
     ('signal = "FlowKgH" }', 'signal = "FlowKgH", unit = "g/s" }'),
     ["[quantities.target_flow.unit]", "'kg/h' by the database", "a factor of 3.6 on every value"]),
    ("missing signal", None, ('signal = "FlowKgH"', 'signal = "FlowKgh"'),
     ["[quantities.target_flow.signal]", "AcmeSetpoint has no signal 'FlowKgh'"]),
    ("required quantity left out", None,
     ('motor_command = { message = "ValveCmd", signal = "MotorMv" }\n', ''),
     ["[quantities.motor_command]", "the rig needs motor_command"]),
    ("too narrow", ('FlowKgH : 39|16@0+ (0.02,0) [0|1000]', 'FlowKgH : 39|16@0+ (0.02,0) [0|500]'),
     None, ["holds 0..500 kg/h", "needs 0..250 g/s = 0..900 kg/h", "too narrow"]),
    ("too coarse", ('RateKgHa : 7|16@0+ (0.1,0)', 'RateKgHa : 7|16@0+ (1,0)'), None,
     ["steps by 1 kg/ha", "needs 0.1 kg/hm2", "too coarse"]),
    ("id clash", (" 784 ", " 1793 "), None,
     ["AcmeSetpoint at 0x701 clashes with the rig's flow module 1 heartbeat"]),
    ("id the wiring fixes", ("BO_ 544 ValveCmd", "BO_ 560 ValveCmd"), None,
     ["ValveCmd is at 0x230", "only reach the rig at 0x220", "analog output module"]),
    ("command layout", ('MotorMv : 0|16@1- (1,0)', 'MotorMv : 16|16@1- (1,0)'), None,
     ["ValveCmd.MotorMv is at bit 16, 16 bits little-endian signed",
      "decodes motor_command at bit 0, 16 bits little-endian signed"]),
    ("command cycle", ('BO_ 544 100;', 'BO_ 544 50;'), None,
     ["once per control period (100 ms)", "the database says 50 ms"]),
    ("cycle off the physics grid", None,
     ('signal = "RateKgHa" }', 'signal = "RateKgHa", cycle_ms = 2.5 }'),
     ["every 2.5 ms", "whole multiple of 1 ms"]),
    ("event-driven cycle", None, ('rows = [1, 2, 3, 4] }\nrow_baseline',
                                  'rows = [1, 2, 3, 4], cycle_ms = 50 }\nrow_baseline'),
     ["row_flow is sent when the rig's model produces it", "asks 50 ms"]),
    ("multiplexer value", None, ('rows = [1, 2, 3, 4] }\nrow_baseline',
                                 'rows = [1, 2, 3, 5] }\nrow_baseline'),
     ["Flow_R4 is in multiplexed frames [4], not [5]"]),
    ("multiplexed signal without a multiplexer", None,
     ('signal = "Flow_R{row}", multiplexer = "RowIdx", rows = [1, 2, 3, 4] }',
      'signal = "Flow_R{row}" }'),
     ["[quantities.row_flow.multiplexer]", "AcmeRowFlow.Flow_R1 is multiplexed",
      "frames with RowIdx = 1", "names no multiplexer"]),
    ("unknown quantity", None, ('enable = {', 'enabled = {'),
     ["no quantity 'enabled'", "the rig needs enable"]),
]


@pytest.mark.parametrize(("what", "dbc", "binding", "words"), MUST_FAIL,
                         ids=[m[0] for m in MUST_FAIL])
def test_a_bad_binding_is_refused_with_the_numbers(fert: Contract, tmp_path: Path, what: str,
                                                   dbc, binding, words) -> None:
    errors = "\n".join(_errors(fert, _acme(tmp_path, dbc=dbc, binding=binding)))
    for word in words:
        assert word in errors, (what, word, errors)
    assert "(fix: " in errors


def test_a_swapped_row_is_refused_and_would_move_the_flow(fert: Contract,
                                                          tmp_path: Path) -> None:
    """Rows 1 and 2 swapped in the multiplexer: each row's signal lives under its own
    multiplexer value, so the check sees it; run anyway, the DUT would read row 1's flow as
    row 2's."""
    swapped = _acme(tmp_path, binding=('rows = [1, 2, 3, 4] }\nrow_baseline',
                                       'rows = [2, 1, 3, 4] }\nrow_baseline'))
    errors = "\n".join(_errors(fert, swapped))
    assert "Flow_R1 is in multiplexed frames [1], not [2]" in errors
    assert "Flow_R2 is in multiplexed frames [2], not [1]" in errors
    right = ContractCodec(fert, load_binding(ACME_BINDING))
    frame = right.encode({"row_flow": 7.5}, row=1)[0]
    frame.data[0] = 2                   # row 1's flow under row 2's value, as swapped
    decoded = right.decode(frame) or {}
    assert decoded["row_flow[2]"] == 7.5 and "row_flow[1]" not in decoded


def _profile(tmp_path: Path, *edits: tuple[str, str], name: str = DAEMON.name) -> Path:
    text = DAEMON.read_text()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


DB_LINE = 'database = "plant_emulators/fertilizer/db/fertilizer.dbc"'


def test_a_profile_bound_to_the_foreign_database_passes(tmp_path: Path) -> None:
    binding = _acme(tmp_path)
    path = _profile(tmp_path, (DB_LINE, f'database = "{tmp_path / ACME_DBC.name}"\n'
                                        f'binding = "{binding}"'))
    outcome = run_cli("profile", "check", str(path))
    assert outcome.code == 0, outcome.stderr
    assert outcome.stdout.startswith("ok")


def test_every_problem_of_a_profile_is_reported_at_once(tmp_path: Path) -> None:
    binding = _acme(tmp_path, dbc=("BO_ 544 ValveCmd", "BO_ 560 ValveCmd"),
                    binding=('signal = "FlowKgH"', 'signal = "FlowKgh"'))
    path = _profile(tmp_path, (DB_LINE, f'database = "{tmp_path / ACME_DBC.name}"\n'
                                        f'binding = "{binding}"'))
    outcome = run_cli("profile", "check", str(path))
    assert outcome.code == 2 and "Traceback" not in outcome.stderr
    errors = [line for line in outcome.stderr.splitlines() if line.startswith("hil: error:")]
    keys = " ".join(errors)
    assert "[quantities.target_flow.signal]" in keys
    assert "[quantities.motor_command.message]" in keys
    # the binding moved the motor command; command_ids [0x220] now names the wrong frame
    assert "[wiring.command_ids]" in keys and "0x230" in keys
    assert all(ACME_BINDING.name in e or path.name in e for e in errors)


def test_a_database_that_moves_a_rig_frame_is_refused_before_the_run(tmp_path: Path) -> None:
    """Issue 31.5: FertSetpoint at 0x300 in the DUT's database, no binding: the rig would send
    it at 0x210; the check says so (it used to pass and fail at run time)."""
    dbc = tmp_path / "moved.dbc"
    dbc.write_text(RIG_DBC.read_text().replace("BO_ 528 FertSetpoint", "BO_ 768 FertSetpoint")
                   .replace("BO_ 528 ", "BO_ 768 ").replace(" 528 ", " 768 "))
    path = _profile(tmp_path, (DB_LINE, f'database = "{dbc}"'))
    outcome = run_cli("profile", "check", str(path))
    assert outcome.code == 2
    assert "[wiring.database] moved.dbc has FertSetpoint at 0x300" in outcome.stderr
    assert "sends and takes it at 0x210" in outcome.stderr and "hil profile bind" in \
        outcome.stderr


def test_command_ids_the_rig_ignores_are_refused(tmp_path: Path) -> None:
    path = _profile(tmp_path, ("command_ids = [0x220]", "command_ids = [0x221]"))
    outcome = run_cli("profile", "check", str(path))
    assert outcome.code == 2
    assert "[wiring.command_ids] [0x221] is not what the rig waits for" in outcome.stderr
    assert "command_ids = [0x220]" in outcome.stderr


def test_the_old_dbc_file_override_points_to_the_binding(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"\[wiring\] binding") as caught:
        load_rig_config(overrides={"wiring": {"dbc_file": str(RIG_DBC)}}, source="p.toml")
    assert caught.value.key == "rig.wiring.dbc_file"
    path = _profile(tmp_path, ("[rig]\n", f'[rig]\nwiring = {{ dbc_file = "{RIG_DBC}" }}\n'))
    outcome = run_cli("profile", "check", str(path))
    assert outcome.code == 2 and "rig.wiring.dbc_file" in outcome.stderr


def test_build_sources_and_profile_dir_resolve_beside_a_relative_profile(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 31.5: ``{profile_dir}`` of a profile named by a relative path is that
    directory, not the project root's namesake; a missing source is reported."""
    firmware = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-firmware.toml"
    work = tmp_path / "mine"
    work.mkdir()
    (work / "src").mkdir()
    (work / "src" / "main.c").write_text("int main(void){return 0;}\n")
    text = firmware.read_text()
    start = text.index("sources = [")
    end = text.index("]", start) + 1
    text = text[:start] + 'sources = ["{profile_dir}/src", "{profile_dir}/gone"]' + text[end:]
    (work / firmware.name).write_text(text)
    monkeypatch.chdir(tmp_path)
    outcome = run_cli("profile", "check", f"mine/{firmware.name}")
    assert outcome.code == 2, outcome
    lines = [line for line in outcome.stderr.splitlines() if "build.sources" in line]
    assert len(lines) == 1 and "'{profile_dir}/gone'" in lines[0]
    assert str(work / "gone") in lines[0]


def test_the_shipped_profiles_pass() -> None:
    profiles = sorted((ROOT / "dut_profiles").glob("*.toml"))
    outcome = run_cli("profile", "check", *map(str, profiles))
    assert outcome.code == 0, outcome.stderr
    assert "hil: error" not in outcome.stderr


def test_copied_database_beside_the_binding(tmp_path: Path, fert: Contract) -> None:
    """A binding names its database relative to itself."""
    shutil.copy(ACME_DBC, tmp_path / "x.dbc")
    (tmp_path / "b.toml").write_text(ACME_BINDING.read_text().replace(ACME_DBC.name, "x.dbc"))
    assert load_binding(tmp_path / "b.toml").database == (tmp_path / "x.dbc").resolve()


@pytest.mark.parametrize(("carrier", "words"), [
    ('{ ddi = 6, element = 1 }', []),                               # mg/m2 at 1: 0.01 kg/ha
    ('{ ddi = 41, element = 1 }', ["mg/s", "cannot convert"]),       # a flow for a rate
    ('{ ddi = 1, element = 1 }', ["mm³/m²", "cannot convert"]),      # a volume rate: unknown
    ('{ ddi = 6, element = [1, 2] }', ["not per row: one element"]),
    ('{ ddi = 60000, element = 1 }', ["not in the rig's DDI table"]),
])
def test_a_ddi_carrier_is_judged_by_the_ddi_table(fert: Contract, tmp_path: Path,
                                                  carrier: str, words: list[str]) -> None:
    path = _acme(tmp_path, binding=('target_rate = { message = "AcmeSetpoint", signal = '
                                    '"RateKgHa" }', f"target_rate = {carrier}"))
    errors = "\n".join(_errors(fert, path))
    if not words:
        assert "target_rate" not in errors, errors
        with pytest.raises(Exception, match="Task Controller"):
            ContractCodec(fert, load_binding(path)).encode({"target_rate": 100.0})
    for word in words:
        assert word in errors, (word, errors)
