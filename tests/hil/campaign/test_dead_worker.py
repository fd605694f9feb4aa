"""A sample that kills its Dask worker is an error sample, and the campaign goes on.

With ``--isolation inprocess`` a sample runs inside the worker process, so a DUT that dies
hard (here: SIGKILL at construction, as a segfaulting native extension would) takes the
worker with it. Dask retries the task once on another worker (``allowed-failures = 1``),
which dies too; the sample must come back as an error sample naming the lost worker, and
the samples after it must still run on the workers the nanny restarts.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.campaign.engine import dask_client, map_samples
from hil.campaign.sample import SampleTask

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"

@pytest.mark.slow
def test_a_sample_that_kills_its_worker_is_an_error_sample(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the workers start with this process's sys.path, not its modules: under
    # --import-mode=importlib this process imports ``tests`` without the checkout on sys.path,
    # so a worker could not import the killer (``No module named 'tests'``: an error sample
    # that never reached the DUT)
    monkeypatch.syspath_prepend(str(ROOT))
    profile = tmp_path / "fertilizer-kills-its-worker-daemon.toml"
    text = REFERENCE.read_text().replace('name = "fertilizer-piecewise-pid-daemon"',
                                         'name = "fertilizer-kills-its-worker-daemon"')
    text = text.replace('inprocess = "reference_controllers.inprocess:fertilizer_piecewise_pid"',
                        'inprocess = "tests.hil.campaign.killer_dut:make"')
    text = text.replace('"plant_emulators/', f'"{ROOT}/plant_emulators/')
    assert "killer_dut:make" in text
    profile.write_text(text)

    def task(path: Path, index: int) -> SampleTask:
        return SampleTask(profile=str(path), index=index, seed=index, bus="inline",
                          keyword="test_flow_step and 23", isolation="inprocess",
                          timeout_s=300.0)

    tasks = [task(profile, 0), task(REFERENCE, 1), task(REFERENCE, 2)]
    samples: list[dict] = []
    with dask_client(workers=2) as client:
        map_samples(client, tasks, samples.append, prefix="dead-worker")
    by_index = {s["index"]: s for s in samples}
    assert sorted(by_index) == [0, 1, 2]
    dead = by_index[0]
    assert dead["verdict"] == "error"
    assert "worker failed" in dead["error"] and "KilledWorker" in dead["error"], dead["error"]
    for i in (1, 2):
        assert by_index[i]["verdict"] in ("pass", "fail"), by_index[i]
        assert by_index[i]["measurements"], by_index[i]
