"""Property tests over every file a user hands agrihil: mutated shipped files are either
accepted or refused with one line naming the file (and the key), never a traceback.

Each property runs the loader API and, for the same bytes, the ``hil`` command that reads the
file (in-process), which must then exit 2 with that one line and write nothing half-way.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.dut.profile import load_profile
from hil.errors import ConfigError
from hil.gate.baseline import load_baseline
from hil.gate.record import load_record
from hil.gate.tolerance import load_tolerances
from hil.rig.registry import load_rig
from tests.fuzz.cli import assert_refused, run_cli
from tests.fuzz.mutate import json_mutations, structural, toml_mutations

ROOT = Path(__file__).resolve().parents[2]
PROFILES = [ROOT / "dut_profiles" / name for name in (
    "fertilizer-piecewise-pid-firmware.toml", "sowing-depth-fuzzy-pid-daemon.toml",
    "physical/fertilizer-physical-ecu.toml")]
SCENARIOS = [ROOT / "plant_emulators" / "fertilizer" / "scenarios" / "fault-sensor-silent.toml",
             ROOT / "plant_emulators" / "sowing_depth" / "scenarios" / "depth-step.toml",
             ROOT / "plant_emulators" / "fertilizer" / "scenarios" / "field-stop-go.toml"]
RIGS = ["fertilizer", "sowing_depth"]
TOLERANCES = ROOT / "ci" / "tolerances.toml"
BASELINE = ROOT / "ci" / "baselines" / "fertilizer-piecewise-pid-firmware.json"
RECORD = ROOT / "tests" / "fuzz" / "data" / "record.json"


def _file_and_mutation(files: list[Path], mutations) -> st.SearchStrategy:
    return st.sampled_from(files).flatmap(lambda p: mutations(p).map(lambda m: (p, m)))


def _write(tmp: Path, name: str, content: bytes) -> Path:
    tmp.mkdir(parents=True, exist_ok=True)
    path = tmp / name
    path.write_bytes(content)
    return path


def _refusal(load, path: Path, what: str) -> ConfigError | None:
    """Load ``path``: None when accepted, the error when refused; anything else fails."""
    try:
        load(path)
    except ConfigError as exc:
        message = str(exc)
        assert "\n" not in message, (what, message)
        assert path.name in message, (what, message)
        return exc
    return None


@given(case=_file_and_mutation(PROFILES, toml_mutations))
def test_mutated_dut_profiles(case, tmp_path_factory: pytest.TempPathFactory) -> None:
    source, (what, content) = case
    path = _write(tmp_path_factory.mktemp("profile"), source.name, content)
    refused = _refusal(load_profile, path, what)
    outcome = run_cli("profile", "check", str(path))
    if refused is None and outcome.code == 0:
        return
    # refused by the loader, or by the command's further checks (parameters the controller
    # does not take): either way one line naming the file
    assert_refused(outcome, path, what)


@given(case=_file_and_mutation(SCENARIOS, toml_mutations))
def test_mutated_scenarios(case, tmp_path_factory: pytest.TempPathFactory) -> None:
    source, (what, content) = case
    rig_name = source.parents[1].name
    rig = load_rig(rig_name)
    tmp = tmp_path_factory.mktemp("scenario")
    path = _write(tmp, source.name, content)
    refused = _refusal(lambda p: rig.load_scenario(str(p)), path, what)
    if refused is None:
        return  # a valid scenario: running it is the rig's tests' business
    out = tmp / "run"
    outcome = run_cli("run", "--rig", rig_name, "--dut", "builtin:pi", "--bus", "inline",
                      "--scenario", str(path), "--out", str(out))
    assert_refused(outcome, path, what)
    assert not out.exists() or not any(out.iterdir()), (what, list(out.iterdir()))


def _rig_config_mutations(rig: str) -> st.SearchStrategy:
    return toml_mutations(ROOT / "plant_emulators" / rig / "rig.toml").map(
        lambda m: (rig, m))


@given(case=st.sampled_from(RIGS).flatmap(_rig_config_mutations))
def test_mutated_rig_configs(case, tmp_path_factory: pytest.TempPathFactory) -> None:
    rig_name, (what, content) = case
    tmp = tmp_path_factory.mktemp("rig")
    (tmp / "db").symlink_to(ROOT / "plant_emulators" / rig_name / "db")
    path = _write(tmp, "rig.toml", content)
    module = __import__(f"plant_emulators.{rig_name}.config", fromlist=["load_rig_config"])
    _refusal(module.load_rig_config, path, what)


@st.composite
def _overrides(draw: st.DrawFn) -> tuple[str, str, dict]:
    import tomllib

    rig = draw(st.sampled_from(RIGS))
    data = tomllib.loads((ROOT / "plant_emulators" / rig / "rig.toml").read_text())
    what, content = draw(structural(data, lambda d: json.dumps(d, allow_nan=True).encode()))
    return rig, what, json.loads(content)


@given(case=_overrides())
def test_mutated_rig_overrides(case, tmp_path_factory: pytest.TempPathFactory) -> None:
    """A profile's ``[rig]`` table: the whole rig config, one key mutated, as overrides."""
    rig_name, what, overrides = case
    rig = load_rig(rig_name)
    try:
        rig.load_config(overrides, source="dut.toml")
    except ConfigError as exc:
        assert "\n" not in str(exc) and "dut.toml" in str(exc), (what, str(exc))


@given(case=json_mutations(BASELINE))
def test_mutated_baselines(case, tmp_path_factory: pytest.TempPathFactory) -> None:
    what, content = case
    tmp = tmp_path_factory.mktemp("baseline")
    path = _write(tmp, "baseline.json", content)
    refused = _refusal(load_baseline, path, what)
    before = path.read_bytes()
    outcome = run_cli("gate", str(RECORD), "--baseline", str(path), "--force",
                      "--summary", str(tmp / "summary.md"))
    if refused is None:
        assert outcome.code in (0, 1), (what, outcome)
    else:
        assert_refused(outcome, path, what)
        assert not (tmp / "summary.md").exists()
    assert path.read_bytes() == before  # never rewritten without --update-baseline


@given(case=json_mutations(RECORD))
def test_mutated_records(case, tmp_path_factory: pytest.TempPathFactory) -> None:
    what, content = case
    tmp = tmp_path_factory.mktemp("record")
    path = _write(tmp, "record.json", content)
    refused = _refusal(load_record, path, what)
    new_baseline = tmp / "new-baseline.json"
    outcome = run_cli("gate", str(path), "--baseline", str(new_baseline), "--update-baseline",
                      "--force", "--summary", str(tmp / "summary.md"))
    if refused is None:
        assert outcome.code in (0, 1, 2), (what, outcome)
        assert "Traceback" not in outcome.stderr
    else:
        assert_refused(outcome, path, what)
        # nothing half-written: no baseline, no summary, no temporary files
        assert sorted(p.name for p in tmp.iterdir()) == ["record.json"], (what,)


@given(case=toml_mutations(TOLERANCES))
def test_mutated_tolerance_files(case, tmp_path_factory: pytest.TempPathFactory) -> None:
    what, content = case
    tmp = tmp_path_factory.mktemp("tolerance")
    path = _write(tmp, "tolerances.toml", content)
    refused = _refusal(load_tolerances, path, what)
    outcome = run_cli("gate", str(RECORD), "--baseline", str(BASELINE), "--force",
                      "--tolerance", str(path), "--summary", str(tmp / "summary.md"))
    if refused is None:
        assert outcome.code in (0, 1), (what, outcome)
    else:
        assert_refused(outcome, path, what)
        assert not (tmp / "summary.md").exists()


def test_the_shipped_files_load() -> None:
    """The mutations start from files that load: a refusal is the mutation's doing."""
    for path in PROFILES:
        load_profile(path)
    for path in SCENARIOS:
        load_rig(path.parents[1].name).load_scenario(str(path))
    load_tolerances(TOLERANCES)
    load_baseline(BASELINE)
    load_record(RECORD)
    assert shutil.which("true")  # sanity of the environment the CLI runs in
