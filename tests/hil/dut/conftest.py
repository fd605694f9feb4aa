from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

TOY = Path(__file__).resolve().parents[2] / "helpers" / "toy_dut.py"


def profile_text(name: str = "toy-good-daemon", behaviour: str = "good", *,
                 extra: str = "", ready: str = "bootup", stop_timeout_s: float = 1.0) -> str:
    return f'''
[dut]
name = "{name}"
version = "0.1.0"
kind = "daemon"
rig = "fertilizer"
controller = "toy"

[launch]
command = ["{{python}}", "{TOY}", "{behaviour}"]
ready = "{ready}"
ready_timeout_s = 10.0
stop_timeout_s = {stop_timeout_s}

[wiring]
node_id = 0x10

[timing]
control_period_ms = 100

[limits]
"flow.step.overshoot" = {{ high = 5.0 }}
{extra}
'''


@pytest.fixture
def write_profile(tmp_path: Path) -> Callable[..., Path]:
    def write(name: str = "toy-good-daemon", text: str | None = None, **kw: object) -> Path:
        path = tmp_path / f"{name}.toml"
        path.write_text(text if text is not None else profile_text(name, **kw))  # type: ignore[arg-type]
        return path
    return write
