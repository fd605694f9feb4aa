"""``--isolation fork``: a fresh process per sample, forked from a preloaded server, measures
exactly what a new interpreter measures, and a hung sample dies with everything it started."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import pytest

from hil.campaign.engine import same_measurements
from hil.campaign.forked import run_forked
from hil.cli.main import main

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"


def _campaign(out: Path, isolation: str) -> dict:
    # one worker: both samples forked from the same server (a second worker would only add
    # its start-up, ~2.5 s of CPU per campaign)
    code = main(["campaign", str(REFERENCE), "--bus", "inline", "--workers", "1",
                 "--samples", "2", "--seed", "21", "-k", "test_flow_step and 23",
                 "--dispersion", "none", "--max-reruns", "0", "--no-progress",
                 "--isolation", isolation, "--out", str(out)])
    assert code == 3      # inconclusive: two samples cannot demonstrate the profile's 0.975
    return json.loads((out / "campaign.json").read_text())


@pytest.mark.slow   # two campaigns (~15-30 s); the default run's campaigns fork their samples
def test_forked_samples_measure_what_new_interpreters_measure(tmp_path: Path) -> None:
    forked = _campaign(tmp_path / "fork", "fork")
    fresh = _campaign(tmp_path / "process", "process")
    assert forked["engine"]["isolation"] == "fork"
    for a, b in zip(forked["samples"], fresh["samples"], strict=True):
        assert a["measurements"] and a["verdict"] == b["verdict"] == "pass"
        assert same_measurements(a["measurements"], b["measurements"])


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie is dead too (its parent, the killed sample, can no longer reap it)
    with open(f"/proc/{pid}/stat") as fh:
        return fh.read().split(")")[-1].split()[0] != "Z"


def test_a_hung_forked_sample_is_killed_with_its_children(tmp_path: Path) -> None:
    pid_file = tmp_path / "child.pid"
    suite = tmp_path / "test_hangs.py"
    suite.write_text(
        "import subprocess, time\n"
        "def test_hangs():\n"
        "    child = subprocess.Popen(['sleep', '120'])\n"
        f"    open({str(pid_file)!r}, 'w').write(str(child.pid))\n"
        "    time.sleep(120)\n")
    log = tmp_path / "pytest.log"
    t0 = time.monotonic()
    code = run_forked([str(suite), "-q", "-p", "no:cacheprovider"], log, timeout_s=4.0)
    assert code is None and time.monotonic() - t0 < 60
    child = int(pid_file.read_text())
    deadline = time.monotonic() + 10
    while _alive(child):
        assert time.monotonic() < deadline, f"the sample's child {child} survived it"
        time.sleep(0.1)


def test_a_forked_sample_returns_its_exit_code_and_output(tmp_path: Path) -> None:
    suite = tmp_path / "test_fails.py"
    suite.write_text("def test_fails():\n    assert 1 == 2, 'the message'\n")
    log = tmp_path / "pytest.log"
    assert run_forked([str(suite), "-q", "-p", "no:cacheprovider"], log, timeout_s=120) == 1
    assert "the message" in log.read_text()


@pytest.mark.parametrize("isolation", ["fork", "process"])
def test_a_sample_past_its_timeout_is_an_error_sample(tmp_path: Path, isolation: str) -> None:
    code = main(["campaign", str(REFERENCE), "--bus", "inline", "--workers", "1",
                 "--samples", "1", "--timeout-s", "0.5", "--max-reruns", "0",
                 "--dispersion", "none", "--no-progress", "--isolation", isolation,
                 "--out", str(tmp_path / "t")])
    doc = json.loads((tmp_path / "t" / "campaign.json").read_text())
    assert code == 2
    [sample] = doc["samples"]
    assert sample["verdict"] == "error" and sample["error"].startswith("timeout")
    assert doc["summary"]["verdict"] == "error"
