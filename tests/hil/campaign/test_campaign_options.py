"""``hil campaign``: every bad option is exit 2 with one line naming it, before any Dask worker
starts; a campaign that cannot start leaves the previous one in ``--out`` as it was; an
unreachable scheduler is said within the connect timeout (issue 30)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from hil.cli.main import main

ROOT = Path(__file__).resolve().parents[3]
REFERENCE = ROOT / "dut_profiles/fertilizer-piecewise-pid-daemon.toml"
BASE = ["campaign", str(REFERENCE), "--samples", "2", "--bus", "inline", "--no-progress",
        "--dispersion", "none"]

BAD = {
    "seed-negative": (["--seed", "-1"], "--seed"),
    "seed-too-big": (["--seed", str(2**63)], "--seed"),
    "timeout-negative": (["--timeout-s", "-5"], "--timeout-s"),
    "timeout-nan": (["--timeout-s", "nan"], "--timeout-s"),
    "timeout-inf": (["--timeout-s", "inf"], "--timeout-s"),
    "max-reruns-negative": (["--max-reruns", "-1"], "--max-reruns"),
    "worst-negative": (["--worst", "-1"], "--worst"),
    "samples-zero": (["--samples", "0"], "--samples"),
    "workers-zero": (["--workers", "0"], "--workers"),
    "connect-timeout-zero": (["--connect-timeout-s", "0"], "--connect-timeout-s"),
    "k-selects-nothing": (["-k", "zzznothing"], "-k"),
    "k-malformed": (["-k", "step or (touch x"], "-k"),
    "bus-unknown": (["--bus", "nosuchbus:0"], "--bus"),
    "suite-unknown": (["--suite", "fast,nosuch"], "--suite"),
    "scheduler-not-an-address": (["--scheduler", "localhost"], "--scheduler"),
    "inline-realtime": (["--clock", "realtime"], "--bus"),
    "dispersion-missing": (["--dispersion", "/nonexistent/d.toml"], "d.toml"),
}


@pytest.fixture
def no_cluster(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Fail the test if a Dask client or cluster is ever asked for."""
    import hil.campaign.engine as engine

    asked: list[Any] = []

    def refuse(**kwargs: Any) -> Any:
        asked.append(kwargs)
        raise AssertionError("a Dask cluster was started before the options were checked")
    monkeypatch.setattr(engine, "dask_client", refuse)
    return asked


def _previous_campaign(out: Path) -> dict[str, str]:
    """A previous campaign's files in ``out``, as a CI workspace would hold them."""
    (out / "samples" / "0001").mkdir(parents=True)
    files = {"campaign.json": json.dumps({"schema": "agrihil.campaign/1", "status": "complete",
                                          "old": True}),
             "samples.jsonl": '{"index": 0}\n', "report.html": "<html>old</html>",
             "samples/0001/record.json": "{}"}
    for name, text in files.items():
        (out / name).write_text(text)
    return files


def _unchanged(out: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        assert (out / name).read_text() == text, name
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_option_is_exit_2_naming_it_before_any_worker(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], no_cluster: list[Any],
        case: str) -> None:
    extra, named = BAD[case]
    out = tmp_path / "c"
    files = _previous_campaign(out)
    assert main([*BASE, "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and named in err, err
    assert "Traceback" not in err
    assert not no_cluster
    _unchanged(out, files)


def test_an_unreachable_scheduler_is_one_line_and_loses_nothing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "c"
    files = _previous_campaign(out)
    code = main([*BASE, "-k", "test_flow_step and 23", "--scheduler", "tcp://127.0.0.1:1",
                 "--connect-timeout-s", "1", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert "--scheduler" in err[-1] and "tcp://127.0.0.1:1" in err[-1] and "1 s" in err[-1]
    _unchanged(out, files)


def test_reruns_are_proportionate_to_the_campaign() -> None:
    from hil.cli.campaign import default_max_reruns

    assert [default_max_reruns(n) for n in (1, 10, 19, 20, 100, 300)] == [1, 1, 1, 2, 10, 10]


def test_the_staged_outputs_are_the_records_files() -> None:
    from hil.campaign import record
    from hil.cli import campaign

    assert campaign.RECORD_NAME == record.RECORD_NAME
    assert record.SAMPLES_NAME in campaign.OUTPUTS
