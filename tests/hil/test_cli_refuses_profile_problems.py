"""``hil run`` and ``hil qualify`` refuse up front what ``hil profile check`` reports (#31.5,
#31.9: a ``wiring.command_ids`` typo used to pass silently)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PROFILE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"


@pytest.fixture
def typo_profile(tmp_path: Path) -> Path:
    text = PROFILE.read_text(encoding="utf-8")
    assert "command_ids = [0x220]" in text
    text = text.replace("command_ids = [0x220]", "command_ids = [0x221]").replace(
        '"plant_emulators/fertilizer/db/fertilizer.dbc"',
        f'"{ROOT / "plant_emulators/fertilizer/db/fertilizer.dbc"}"')
    path = tmp_path / "profiles" / PROFILE.name
    path.parent.mkdir()
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("command", [
    ["qualify", "{profile}", "--bus", "inline", "--out", "{out}", "-k", "flow_step and 23"],
    ["run", "--rig", "fertilizer", "--dut", "{profile}", "--scenario", "bench-step-23",
     "--out", "{out}"],
])
def test_a_command_ids_typo_is_refused_before_any_run(command: list[str], typo_profile: Path,
                                                      tmp_path: Path) -> None:
    out = tmp_path / "out"
    argv = [a.format(profile=typo_profile, out=out) for a in command]
    done = subprocess.run([sys.executable, "-m", "hil", *argv], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2, done.stdout[-2000:] + done.stderr[-2000:]
    assert f"{typo_profile}: [wiring.command_ids]" in done.stderr
    assert "0x220" in done.stderr and "Traceback" not in done.stderr
    assert not out.exists() or not any(out.iterdir())
