"""The cluster path for real: a ``dask scheduler`` and two ``dask worker`` processes on
loopback, the campaign sent through ``--scheduler``, and every sample identical to the same
campaign on the embedded LocalCluster."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from hil.campaign.engine import same_measurements
from hil.cli.main import main

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"


def _dask(*args: str) -> list[str]:
    return [sys.executable, "-m", "distributed.cli." + args[0], *args[1:]]


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[str]:
    """A scheduler on an ephemeral loopback port and two single-threaded workers."""
    info = tmp_path / "scheduler.json"
    procs = [subprocess.Popen(_dask("dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                                    "--no-dashboard", "--scheduler-file", str(info)),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)]
    try:
        deadline = time.monotonic() + 60
        while not info.exists() or not info.read_text().strip():
            assert time.monotonic() < deadline, "the dask scheduler did not start"
            time.sleep(0.2)
        time.sleep(0.2)
        address = json.loads(info.read_text())["address"]
        for _ in range(2):
            procs.append(subprocess.Popen(
                _dask("dask_worker", address, "--nthreads", "1", "--host", "127.0.0.1",
                      "--no-dashboard", "--memory-limit", "0"),
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                cwd=tmp_path))
        from dask.distributed import Client

        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=90)
        yield address
    finally:
        for proc in reversed(procs):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
        for proc in procs:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


@pytest.mark.slow
def test_cluster_campaign_equals_the_local_one(tmp_path: Path, cluster: str) -> None:
    common = ["campaign", str(REFERENCE), "--samples", "3", "--seed", "11", "--bus", "inline",
              "--max-reruns", "0", "--no-progress"]
    main([*common, "--scheduler", cluster, "--out", str(tmp_path / "remote")])
    main([*common, "--workers", "2", "--out", str(tmp_path / "local")])
    remote = json.loads((tmp_path / "remote" / "campaign.json").read_text())
    local = json.loads((tmp_path / "local" / "campaign.json").read_text())
    assert remote["engine"]["kind"] == "scheduler" and remote["engine"]["workers"] == 2
    assert local["engine"]["kind"] == "local"
    # the two workers of the cluster both ran samples (not one doing everything)
    assert len({s["worker"] for s in remote["samples"]}) == 2
    assert [s["index"] for s in remote["samples"]] == [0, 1, 2]
    for r, lo in zip(remote["samples"], local["samples"], strict=True):
        assert r["verdict"] == lo["verdict"] and r["seed"] == lo["seed"] == 11 + r["index"]
        assert r["overrides"] == lo["overrides"]
        assert same_measurements(r["measurements"], lo["measurements"])
        assert r["error"] is None
    assert remote["summary"]["verdict"] == local["summary"]["verdict"]
    assert remote["measurements"] == local["measurements"]
    # the fork server needs workers that may start processes; `dask worker` starts daemonic
    # ones, so --isolation fork there is an error sample that says what to do
    code = main(["campaign", str(REFERENCE), "--samples", "1", "--bus", "inline",
                 "-k", "test_flow_step and 23", "--max-reruns", "0", "--no-progress",
                 "--isolation", "fork", "--scheduler", cluster, "--out", str(tmp_path / "f")])
    forked = json.loads((tmp_path / "f" / "campaign.json").read_text())
    assert code == 2 and "DASK_DISTRIBUTED__WORKER__DAEMON=False" in forked["samples"][0]["error"]
