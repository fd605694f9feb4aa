"""Profiles of synthetic DUTs for the reliability tests."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

DYING = Path(__file__).resolve().parent / "dying_dut.py"


def dying_profile_text(name: str, how: str) -> str:
    return f'''
[dut]
name = "{name}"
version = "0.1.0"
kind = "daemon"
rig = "fertilizer"
controller = "toy"

[launch]
command = ["{{python}}", "{DYING}", "{how}"]
ready = "bootup"
ready_timeout_s = 20.0
stop_timeout_s = 1.0

[wiring]
node_id = 0x10
command_ids = [0x220]

[timing]
control_period_ms = 100

[limits]
"flow.step.overshoot" = {{ high = 5.0 }}
'''


@pytest.fixture
def dying_profile(tmp_path: Path) -> Callable[[str], Path]:
    def write(how: str) -> Path:
        name = "toy-" + how.replace(":", "-") + "-daemon"
        path = tmp_path / f"{name}.toml"
        path.write_text(dying_profile_text(name, how))
        return path
    return write
