"""``hil report QUAL_DIR``: exit 0 with the page written, exit 2 naming a bad record."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from hil.cli.main import main


def _minimal(**extra: Any) -> dict[str, Any]:
    return {"schema": "agrihil.qualification/1", "verdict": "pass", **extra}


def test_report_writes_the_page_and_exits_0(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "record.json").write_text(json.dumps(_minimal(dut={"name": "x"})))
    opened: list[str] = []
    monkeypatch.setattr("webbrowser.open", lambda url: opened.append(url) or True)
    assert main(["report", str(tmp_path), "--open"]) == 0
    page = tmp_path / "report.html"
    assert page.exists() and "PASS" in page.read_text()
    assert str(page) in capsys.readouterr().out
    assert opened == [page.resolve().as_uri()]
    # regenerating overwrites, leaves no temporary file
    assert main(["report", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["record.json", "report.html"]


@pytest.mark.parametrize(("content", "why"), [
    (None, "no qualification record here"),
    ("{not json", "not valid JSON"),
    ("[1, 2]", "must hold a JSON object"),
    (json.dumps({"run_id": "x", "verdict": "pass"}), "not a qualification record"),
    (json.dumps({"schema": "agrihil.qualification/9"}), "unsupported schema"),
    (json.dumps(_minimal(measurements={"a": 1})), "'measurements' must be a list"),
    (json.dumps(_minimal(runs=[1])), "'runs[0]' must be an object"),
    (json.dumps(_minimal(dut="x")), "'dut' must be an object"),
])
def test_a_bad_record_exits_2_naming_the_file(tmp_path: Path, content: str | None, why: str,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    if content is not None:
        (tmp_path / "record.json").write_text(content)
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path / "record.json") in err and why in err, err
    assert not (tmp_path / "report.html").exists()


def test_a_run_record_is_not_a_qualification_record(real_runs: dict[str, Path],
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(real_runs["step"])]) == 2
    assert "a single run's record.json is not one" in capsys.readouterr().err
