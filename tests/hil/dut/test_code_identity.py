"""The record names the code under test, and ``hil profile check`` refuses a DUT whose program
is missing (issue 43).

The identity of a DUT (``DutProfile.identity()``, the record's ``dut``) carries ``code``: the
program its command runs with its SHA-256 (a daemon's script or module, a firmware's binary
once built), and the git revision and dirty flag of its files.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from hil.cli.main import main
from hil.dut import code_identity
from hil.dut.build import ensure_built
from hil.dut.code_identity import program_of
from hil.dut.profile import load_profile

from .conftest import TOY, profile_text

ROOT = Path(__file__).resolve().parents[3]


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(repo), *args], check=True, capture_output=True,
                          text=True).stdout.strip()


def _daemon(tmp_path: Path, command: str, name: str = "toy-good-daemon") -> Path:
    text = profile_text(name).replace(f'command = ["{{python}}", "{TOY}", "good"]', command)
    assert command in text
    path = tmp_path / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(("command", "says"), [
    ('command = ["{python}", "{profile_dir}/gone.py"]', "gone.py does not exist"),
    ('command = ["{python}", "-u", "-m", "no_such_module_xyz"]',
     "module 'no_such_module_xyz' cannot be found"),
    ('command = ["{profile_dir}/no-such-binary", "--bus", "{bus}"]',
     "no-such-binary does not exist"),
])
def test_profile_check_refuses_a_daemon_whose_program_is_missing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, says: str) -> None:
    path = _daemon(tmp_path, command)
    assert main(["profile", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: [launch.command]" in err and says in err, err
    assert "Traceback" not in err


def test_the_program_of_a_command() -> None:
    module = program_of([sys.executable, "-m", "reference_controllers.daemon", "--bus", "x"])
    assert module.path == ROOT / "reference_controllers" / "daemon.py" and not module.problem
    assert program_of([sys.executable, "-c", "print(1)"]).path is None
    assert program_of(["sh", str(TOY)]).path == TOY
    assert "not a command on PATH" in program_of(["no-such-cmd-xyz"]).problem


def test_a_daemons_identity_names_its_script_and_git_state(tmp_path: Path) -> None:
    repo = tmp_path / "ctrl"
    repo.mkdir()
    script = repo / "controller.py"
    script.write_text(TOY.read_text(encoding="utf-8"), encoding="utf-8")
    _git(repo, "init", "-q")
    _git(repo, "add", "controller.py")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "c")
    profile = load_profile(_daemon(repo, 'command = ["{python}", "{profile_dir}/controller.py",'
                                         ' "good"]'))
    identity = profile.identity()
    assert identity["build_id"] == ""                         # the user's, untouched
    code = identity["code"]
    assert code["program"]["sha256"] == _sha(script)
    assert code["program"]["path"] == "controller.py"         # relative to its work tree
    assert code["git"] == {"revision": _git(repo, "rev-parse", "HEAD"), "dirty": False}
    script.write_text(script.read_text(encoding="utf-8") + "\n# changed\n", encoding="utf-8")
    # the program's hash follows the file at once; the git state is taken once per process
    # (a qualification names the tree it started from), so a new process sees it dirty
    assert profile.identity()["code"]["program"]["sha256"] == _sha(script)
    assert profile.identity()["code"]["git"]["dirty"] is False
    code_identity._git_state.cache_clear()
    assert profile.identity()["code"]["git"]["dirty"] is True


def test_outside_a_work_tree_there_is_no_git_state(tmp_path: Path) -> None:
    script = tmp_path / "controller.py"
    script.write_text("print('hi')\n", encoding="utf-8")
    profile = load_profile(_daemon(tmp_path, 'command = ["{python}", '
                                             '"{profile_dir}/controller.py"]'))
    code = profile.identity()["code"]
    if code.get("git") is None:      # (tmp_path may itself sit in a work tree elsewhere)
        assert "git" not in code
    assert code["program"]["sha256"] == _sha(script)


FIRMWARE = '''
[dut]
name = "toy-fw-firmware"
version = "0.1.0"
kind = "firmware"
rig = "fertilizer"
controller = "toy"

[build]
command = ["sh", "-c", "cp {profile_dir}/src/fw.sh {build_dir}/fw && chmod +x {build_dir}/fw"]
sources = ["{profile_dir}/src"]
artifacts = [ARTIFACTS]

[launch]
command = ["LAUNCH", "--bus", "{bus}"]

[wiring]
node_id = 0x10

[timing]
control_period_ms = 100
'''


@pytest.fixture
def firmware(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Callable[..., Path]:
    monkeypatch.setenv("AGRIHIL_CACHE", str(tmp_path / "cache"))
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "fw.sh").write_text("#!/bin/sh\nexit 0\n", encoding="utf-8")

    def write(artifacts: str = '"{build_dir}/fw"', launch: str = "{build_dir}/fw") -> Path:
        path = tmp_path / "toy-fw-firmware.toml"
        path.write_text(FIRMWARE.replace("ARTIFACTS", artifacts).replace("LAUNCH", launch),
                        encoding="utf-8")
        return path
    return write


def test_a_firmware_whose_binary_the_build_does_not_list_is_refused(
        firmware: Callable[..., Path], capsys: pytest.CaptureFixture[str]) -> None:
    path = firmware(launch="{build_dir}/other")
    assert main(["profile", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: [build.artifacts] the launch command runs {{build_dir}}/other" in err


def test_a_firmware_whose_build_leaves_out_its_binary_is_refused_after_the_build(
        firmware: Callable[..., Path], capsys: pytest.CaptureFixture[str]) -> None:
    path = firmware(artifacts='"{build_dir}/fw", "{build_dir}/fw.map"')
    assert main(["profile", "check", "-q", str(path)]) == 0        # not built: a note
    assert "not built yet" in capsys.readouterr().err
    assert main(["profile", "check", "--build", str(path)]) == 2
    err = capsys.readouterr().err
    assert "[build.artifacts] the build did not produce" in err and "fw.map" in err


def test_a_built_firmwares_identity_is_its_binary(firmware: Callable[..., Path],
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    path = firmware()
    assert main(["profile", "check", "-q", "--build", str(path)]) == 0
    assert "not built yet" not in capsys.readouterr().err
    profile = load_profile(path)
    built = ensure_built(profile)
    binary = Path(str(built["build_dir"])) / "fw"
    code = profile.identity()["code"]
    assert code["program"] == {"path": "{build_dir}/fw", "sha256": _sha(binary),
                               "bytes": binary.stat().st_size, "what": "executable"}
    assert code["source_sha256"] == built["source_sha256"]
    # the binary goes missing from the cache entry: refused, naming launch.command
    binary.unlink()
    assert main(["profile", "check", "-q", str(path)]) == 2
    assert f"{path}: [launch.command]" in capsys.readouterr().err


FMU = '''
[dut]
name = "toy-fmu"
version = "0.1.0"
kind = "fmu"
rig = "fertilizer"
controller = "toy"

[build]
command = ["sh", "-c", "cp {profile_dir}/src/fw.sh {build_dir}/toy.fmu"]
sources = ["{profile_dir}/src"]
artifacts = ["{build_dir}/toy.fmu"]

[fmu]
path = "{build_dir}/toy.fmu"
level = "signal"

[wiring]
node_id = 0x10

[timing]
control_period_ms = 100
'''


def test_an_fmus_identity_is_its_fmu_file(tmp_path: Path,
                                          firmware: Callable[..., Path]) -> None:
    path = tmp_path / "toy-fmu.toml"
    path.write_text(FMU, encoding="utf-8")
    profile = load_profile(path)            # (the FMU is checked once it exists: not yet)
    code = profile.identity()["code"]
    assert code["program"] == {"path": "{build_dir}/toy.fmu", "sha256": None, "what": "fmu",
                               "note": "not built yet"}
    built = ensure_built(profile)
    fmu = Path(str(built["build_dir"])) / "toy.fmu"
    code = profile.identity()["code"]
    assert code["program"]["sha256"] == _sha(fmu) and code["program"]["what"] == "fmu"
    assert code["source_sha256"] == built["source_sha256"]


def test_hil_run_refuses_a_missing_script_before_any_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _daemon(tmp_path, 'command = ["{python}", "{profile_dir}/gone.py"]')
    out = tmp_path / "out"
    assert main(["run", "--rig", "fertilizer", "--dut", str(path), "--scenario",
                 "bench-step-23", "--out", str(out)]) == 2
    assert f"{path}: [launch.command] the script it runs:" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())
