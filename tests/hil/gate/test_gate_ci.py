"""The CI examples in ci/: the workflows parse and run the documented commands."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

yaml = pytest.importorskip("yaml", reason="PyYAML is not installed: the workflow files are "
                                          "not parsed (GitHub parses them when they run)")

ROOT = Path(__file__).resolve().parents[3]
GATE = ("hil gate qual/record.json --baseline \"$BASELINE\" --tolerance ci/tolerances.toml")


def _workflow(name: str) -> dict[str, Any]:
    data = yaml.safe_load((ROOT / "ci" / "github" / name).read_text(encoding="utf-8"))
    assert isinstance(data, dict)
    return data


def _runs(job: dict[str, Any]) -> str:
    return "\n".join(step.get("run", "") for step in job["steps"])


def _triggers(data: dict[str, Any]) -> Any:
    return data.get("on", data.get(True))      # YAML 1.1 reads a bare `on` key as true


def test_the_vcan_workflow_sets_up_kernel_can_builds_qualifies_gates_and_uploads() -> None:
    data = _workflow("agrihil-vcan.yml")
    assert set(_triggers(data)) == {"push", "pull_request", "workflow_dispatch"}
    job = data["jobs"]["qualify"]
    assert job["runs-on"] == "ubuntu-latest"
    assert job["env"]["BASELINE"] == "ci/baselines/fertilizer-piecewise-pid-firmware.json"
    runs = _runs(job)
    for line in ('sudo apt-get install -y "linux-modules-extra-$(uname -r)"',
                 "sudo modprobe vcan", "sudo ip link add dev vcan0 type vcan",
                 "sudo ip link set up vcan0", "cmake -S firmware -B firmware/build",
                 "cmake --build firmware/build", "pip install .",
                 'hil qualify "$PROFILE" --bus socketcan:vcan0 --clock lockstep --out qual',
                 GATE):
        assert line in runs
    upload = job["steps"][-1]
    assert upload["uses"].startswith("actions/upload-artifact@")
    assert upload["with"]["path"] == "qual/"


def test_the_softbus_workflow_needs_no_kernel_can() -> None:
    job = _workflow("agrihil-softbus.yml")["jobs"]["qualify"]
    runs = _runs(job)
    assert 'hil qualify "$PROFILE" --bus softbus --clock lockstep --out qual' in runs
    assert GATE in runs and "cmake --build firmware/build" in runs
    assert "vcan" not in runs and "modprobe" not in runs and "linux-modules" not in runs
    assert job["steps"][-1]["with"]["path"] == "qual/"


@pytest.mark.parametrize("name", ["agrihil-vcan.yml", "agrihil-softbus.yml"])
def test_the_gate_runs_even_when_qualify_failed(name) -> None:
    steps = _workflow(name)["jobs"]["qualify"]["steps"]
    (gate,) = [s for s in steps if s.get("run", "").startswith("hil gate")]
    assert "!cancelled()" in gate["if"] and "hashFiles('qual/record.json')" in gate["if"]
