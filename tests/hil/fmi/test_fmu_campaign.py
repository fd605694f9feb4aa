"""FMU DUTs in campaigns: an FMU instance per sample on the embedded Dask cluster, and an FMU
that crashes (abort() in its C code, which takes its host process with it) fails that sample,
as a dying DUT process does, while the other samples run."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.campaign.engine import dask_client, map_samples
from hil.campaign.sample import SampleTask

ROOT = Path(__file__).resolve().parents[3]
LSBUS = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-fmu-lsbus.toml"


def crashing_profile(tmp_path: Path, fmus: Path) -> Path:
    """The probe FMU wired as the fertilizer controller, aborting at its first SYNC."""
    text = LSBUS.read_text(encoding="utf-8")
    head = text.split("\n[build]\n")[0].replace('name = "fertilizer-piecewise-pid-fmu-lsbus"',
                                                'name = "fertilizer-crashing-fmu"')
    tail = "[wiring]" + text.split("[wiring]", 1)[1]
    tail = tail.replace('mode = "physical"\n', "crash_at_step = 1\n").replace(
        "ff_coeff = 4.390\n", "")
    fmu = f'\n[fmu]\npath = "{fmus / "agrihil-lsbus-probe.fmu"}"\nlevel = "bus"\n\n'
    path = tmp_path / "fertilizer-crashing-fmu.toml"
    path.write_text((head + fmu + tail).replace('"plant_emulators/',
                                                f'"{ROOT}/plant_emulators/'), encoding="utf-8")
    return path


@pytest.mark.slow
@pytest.mark.parametrize("isolation", ["fork", "inprocess"])
def test_an_fmu_campaign_runs_and_a_crashing_fmu_is_its_samples_error(
        tmp_path: Path, fmus: Path, monkeypatch: pytest.MonkeyPatch, isolation: str) -> None:
    monkeypatch.syspath_prepend(str(ROOT))
    crashing = crashing_profile(tmp_path, fmus)

    def task(path: Path, index: int) -> SampleTask:
        return SampleTask(profile=str(path), index=index, seed=index, bus="inline",
                          keyword="test_flow_step and 23", isolation=isolation,
                          timeout_s=600.0)

    tasks = [task(crashing, 0), task(LSBUS, 1), task(LSBUS, 2)]
    samples: list[dict] = []
    with dask_client(workers=2) as client:
        map_samples(client, tasks, samples.append, prefix=f"fmu-{isolation}")
    by_index = {s["index"]: s for s in samples}
    assert sorted(by_index) == [0, 1, 2]
    # the FMU's host died, not the sample's process: its tests failed naming the DUT's stop
    assert by_index[0]["verdict"] == "fail", by_index[0]
    assert by_index[0]["failed_tests"], by_index[0]
    for i in (1, 2):     # each sample its own FMU instance, measured
        assert by_index[i]["verdict"] == "pass", by_index[i]
        assert by_index[i]["measurements"], by_index[i]
