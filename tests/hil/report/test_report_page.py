"""The report of a qualification with real runs: order, content, highlighting, self-containment."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path
from typing import Any

from hil.report.record import conditions_label

DATA_URI = re.compile(r'data:image/png;base64,[A-Za-z0-9+/=]+')


def test_the_page_parses_with_balanced_tags(qual_page: tuple[Path, str], parse: Any) -> None:
    qual_dir, html = qual_page
    assert (qual_dir / "report.html").exists()
    page = parse(html)
    assert page.problems == []
    assert html.startswith("<!DOCTYPE html>")
    assert len(page.ids) == len(set(page.ids)), "duplicate ids"


def test_verdict_first_then_measurements_then_identity(qual_page: tuple[Path, str]) -> None:
    _, html = qual_page
    verdict = html.index('id="verdict"')
    # the verdict and the table in the first screenful (tests/browser checks it in Chromium)
    assert verdict < html.index('<table class="measurements"') < html.index('id="identity"')
    assert html.index('class="verdict-word">FAIL<') < html.index('<table class="measurements"')
    assert "fertilizer-pi &lt;test&gt; 1.0.0 (build abc123)" in html
    assert 'class="verdict v-fail"' in html
    # counts, each measurement once: 2 pass, 1 marginal pass, 2 fail, 1 error, 1 info
    for count, key, label in ((2, "pass", "pass"), (1, "marginal", "marginal pass"),
                              (2, "fail", "fail"), (1, "error", "error"), (1, "info", "info")):
        assert f'<span class="chip c-{key}"><b>{count}</b> {label}</span>' in html


def test_identity_of_dut_and_bench(qual_page: tuple[Path, str]) -> None:
    qual_dir, html = qual_page
    record = json.loads((qual_dir / "record.json").read_text())
    for value in ("1.0.0", "abc123", "dut_profiles/fertilizer-pi.toml", "9" * 64, "e" * 64,
                  "lockstep", "inline", "2026-11-22 10:00:00 UTC", "3.11.7"):
        assert value in html, value
    assert "fertilizer-pi &lt;test&gt;" in html and "fertilizer-pi <test>" not in html
    assert record["run_id"] in html


def _measurement_rows(page: Any) -> list[tuple[str, list[str]]]:
    return [(cls, cells) for cls, cells in page.tables["measurements"] if cls.startswith("m-")]


def test_every_measurement_appears_with_its_outcome(qual_page: tuple[Path, str],
                                                    parse: Any) -> None:
    qual_dir, html = qual_page
    record = json.loads((qual_dir / "record.json").read_text())
    rows = _measurement_rows(parse(html))
    seen = {(cells[0].split(" ")[0], cells[1], cells[6]) for _, cells in rows}
    assert len(rows) == len(record["measurements"])
    for m in record["measurements"]:
        word = "PASS · MARGINAL" if m["marginal"] else m["outcome"].upper()
        label = conditions_label(m["conditions"]) or "—"
        assert (m["name"], label, word) in seen, (m["name"], label, word)


def test_failures_come_first_and_are_highlighted(qual_page: tuple[Path, str],
                                                 parse: Any) -> None:
    _, html = qual_page
    rows = _measurement_rows(parse(html))
    classes = [cls for cls, _ in rows]
    # the first group is one with a failure, and inside it the failure leads
    assert classes[0] == "m-fail"
    failed = [cells[0] for cls, cells in rows if cls == "m-fail"]
    assert any(c.startswith("flow.step.steady_state_error") for c in failed)
    assert any(c.startswith("flow.field.accuracy") for c in failed)
    assert "m-marginal" in classes and "m-error" in classes and "m-info" in classes
    assert re.search(r"tr\.m-fail td[^{]*\{[^}]*background", html)
    # the verdict lists why it failed: failed measurements, then tests that failed otherwise
    verdict = html[html.index('id="verdict"'):html.index('id="identity"')]
    assert "FAIL flow.step.steady_state_error (target_gps=23): 7.5 %, limit ≤ 5" in verdict
    assert ("test test_suites/fertilizer/test_restart.py::test_restart error: DutError: the "
            "DUT exited") in verdict
    assert "test_step[23] failed" not in verdict   # explained by its measurement


def test_images_are_embedded_pngs_and_nothing_is_external(qual_page: tuple[Path, str],
                                                         parse: Any) -> None:
    _, html = qual_page
    page = parse(html)
    # a step response, a field run, the per-condition chart of flow.field.accuracy
    assert len(page.images) >= 3
    for img in page.images:
        assert img["src"].startswith("data:image/png;base64,")
        assert base64.b64decode(img["src"].split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
        assert img["alt"]
    without_images = DATA_URI.sub("", html)
    assert "http" not in without_images.lower()
    assert 'src="/' not in without_images and "<script" not in without_images
    assert "@import" not in without_images and "url(" not in without_images
    assert "<link" not in without_images and "<iframe" not in without_images
    for href in page.hrefs:
        assert href.startswith("#") or not re.match(r"^(/|[a-z]+:)", href), href


def test_run_links_are_relative_and_point_at_artifacts(qual_page: tuple[Path, str],
                                                      parse: Any) -> None:
    qual_dir, html = qual_page
    hrefs = parse(html).hrefs
    for name in ("bus.log", "bus.asc", "traces.npz", "record.json"):
        assert f"runs/test_step-23/{name}" in hrefs
    for href in hrefs:
        if not href.startswith("#"):
            assert (qual_dir / href).exists(), href
    # every in-page anchor lands somewhere
    ids = set(parse(html).ids)
    assert {h[1:] for h in hrefs if h.startswith("#")} <= ids


def test_missing_traces_and_errors_are_shown_not_raised(qual_page: tuple[Path, str]) -> None:
    _, html = qual_page
    assert "runs/test_fault-sensor-silent/traces.npz missing: no plot of this run" in html
    assert "runs/test_restart/traces.npz missing" in html
    errors = html[html.index('id="errors"'):]
    assert "panic: flow table &lt;corrupt&gt; &amp; exiting" in errors
    assert "<corrupt>" not in html
    assert "DutError: the DUT process exited with status 3" in errors
    assert "test_suites/fertilizer/test_restart.py::test_restart" in errors


def test_plots_timing_runs_and_tests_sections(qual_page: tuple[Path, str], parse: Any) -> None:
    _, html = qual_page
    page = parse(html)
    alts = [img["alt"] for img in page.images]
    assert any(a.startswith("step run runs/test_step-23") for a in alts)
    assert any(a.startswith("field run runs/test_field-6kmh") for a in alts)
    assert "flow.field.accuracy per condition" in alts
    assert "lockstep: virtual time, no lateness" in html
    runs = [cells for cls, cells in page.tables["runs"] if cls.startswith("r-")]
    assert [cells[0] for cells in runs] == ["runs/test_step-23", "runs/test_field-6kmh",
                                            "runs/test_restart",
                                            "runs/test_fault-sensor-silent"]
    # a run's result is the worst of its measurements, or its own verdict when it errored
    assert [cells[2] for cells in runs] == ["FAIL", "PASS", "ERROR", "FAIL"]
    tests = [cells for cls, cells in page.tables["tests"] if cls.startswith("t-")]
    assert [c[1] for c in tests] == ["FAILED", "PASSED", "ERROR"]
    assert "limits with no measurement in this record: flow.restart.recovery_time" in html
    order = [html.index(f'id="{key}"') for key in
             ("measurements", "plots-step", "plots-field", "per-condition", "timing", "runs",
              "tests", "errors")]
    assert order == sorted(order)


def test_the_page_stays_small(qual_page: tuple[Path, str]) -> None:
    qual_dir, _ = qual_page
    assert (qual_dir / "report.html").stat().st_size < 400_000
