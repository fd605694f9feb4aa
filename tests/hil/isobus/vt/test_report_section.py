"""The report's "What the operator saw" section from a run's VT record and screens."""

from __future__ import annotations

import base64
from html.parser import HTMLParser
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from hil.isobus.vt.bench import VtBench
from hil.isobus.vt.screens import ScreenRecorder, vt_record, write_vt_record
from hil.report.record import RunRef
from hil.report.rundata import RunData
from hil.report.sections_vt import vt_section

from .pools import IDS, implement_pool


class Tags(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.images: list[dict[str, Any]] = []
        self.hrefs: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "img":
            self.images.append(dict(attrs))
        if tag == "a":
            self.hrefs.append(str(dict(attrs)["href"]))


def run_with_vt(qual_dir: Path) -> RunData:
    run_dir = qual_dir / "runs" / "vt-run"
    bench = VtBench([implement_pool().to_bytes()], version_label=b"SPR1")
    recorder = ScreenRecorder(bench.vt, run_dir / "vt")
    bench.run_until(3.0)
    assert bench.client is not None
    bench.client.change_active_mask(IDS.ws, IDS.settings)
    bench.run_until(4.0)
    write_vt_record(run_dir, bench.vt, recorder)
    return RunData(RunRef("runs/vt-run", "vt-scenario", "pass", 4.0, 1.0), run_dir, "fert")


def test_screens_on_the_time_line_with_the_pool_identity(tmp_path: Path) -> None:
    run = run_with_vt(tmp_path)
    qual = SimpleNamespace(path=tmp_path / "record.json")
    html = vt_section(qual, [run])          # type: ignore[arg-type]
    assert html.startswith('<section id="vt-screens">')
    pool = implement_pool()
    assert f"{pool.size:,} bytes" in html and pool.sha256[:16] in html
    assert "SPR1" in html and "vt-scenario" in html
    tags = Tags()
    tags.feed(html)
    assert len(tags.images) == 2
    for img in tags.images:
        assert img["src"].startswith("data:image/png;base64,")
        assert base64.b64decode(img["src"].split(",", 1)[1])[:4] == b"\x89PNG"
    assert tags.hrefs == ["runs/vt-run/vt/screen-0001.png", "runs/vt-run/vt/screen-0002.png"]
    assert all((tmp_path / h).is_file() for h in tags.hrefs)
    assert f"mask {IDS.home} · pool active" in html
    assert f"mask {IDS.settings} · active mask {IDS.settings}" in html


def test_no_section_without_a_vt_and_a_broken_record_is_a_note(tmp_path: Path) -> None:
    plain = tmp_path / "runs" / "plain"
    plain.mkdir(parents=True)
    run = RunData(RunRef("runs/plain", "s", "pass", 1.0, 1.0), plain, "fert")
    qual = SimpleNamespace(path=tmp_path / "record.json")
    assert vt_section(qual, [run]) == ""    # type: ignore[arg-type]
    (plain / "vt").mkdir()
    (plain / "vt" / "vt.json").write_text("{not json")
    assert vt_section(qual, [run]) == ""    # type: ignore[arg-type]
    assert "vt/vt.json cannot be read" in run.notes[0]


def test_a_field_runs_screens_from_its_record(tmp_path: Path) -> None:
    """A rig's field run carries the VT's record and the screens' PNGs in its record
    (``truth.field_run.vt``, as :meth:`hil.isobus.vt.fieldvt.FieldVt.record` writes it): the
    same section, each thumbnail opening its full screen in place (no file to link to)."""
    bench = VtBench([implement_pool().to_bytes()], version_label=b"SPR1")
    recorder = ScreenRecorder(bench.vt, None, keep_images=True)
    bench.run_until(3.0)
    record = {**vt_record(bench.vt, recorder),
              "screen_images": {name: base64.b64encode(png).decode("ascii")
                                for name, png in recorder.images.items()}}
    assert record["screens"] and set(record["screen_images"]) == {
        s["file"] for s in record["screens"]}
    run_dir = tmp_path / "runs" / "field"
    run_dir.mkdir(parents=True)
    run = RunData(RunRef("runs/field", "isobus-vt-operator", "pass", 3.0, 1.0), run_dir,
                  "fert", record={"truth": {"field_run": {"vt": record}}})
    html = vt_section(SimpleNamespace(path=tmp_path / "record.json"), [run])  # type: ignore
    tags = Tags()
    tags.feed(html)
    thumbs = [i for i in tags.images if i.get("width")]
    full = [i for i in tags.images if not i.get("width")]
    assert len(thumbs) == len(full) == len(record["screens"]) and not tags.hrefs
    assert all(i["src"].startswith("data:image/png;base64,") for i in tags.images)
    assert "<details>" in html and "SPR1" in html and "isobus-vt-operator" in html
