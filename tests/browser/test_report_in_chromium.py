"""The qualification report in a real browser (#18): headless Chromium over the DevTools
protocol loads report.html at 1366x768 and checks what a reader relies on: no console error,
every internal link and anchor resolves, nothing is fetched from outside the file, the verdict
banner and the measurement table are in the first screenful; the failing report of a
must-fail DUT says FAIL first and lists its failing rows first."""

from __future__ import annotations

from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlparse

import pytest

from .cdp import Chromium

WIDTH, HEIGHT = 1366, 768

_PAGE_FACTS = """(() => {
  const box = el => {
    if (!el) return null;
    const r = el.getBoundingClientRect(), s = getComputedStyle(el);
    return {top: r.top, bottom: r.bottom, left: r.left, right: r.right, height: r.height,
            shown: s.display !== 'none' && s.visibility !== 'hidden' && r.height > 0};
  };
  const table = document.querySelector('table.measurements');
  const rows = table ? Array.from(table.querySelectorAll('tbody tr')) : [];
  const firstData = rows.find(r => /(^| )m-/.test(r.className));
  return {
    title: document.title,
    verdictWord: (document.querySelector('.verdict-word') || {}).textContent || '',
    verdict: box(document.getElementById('verdict')),
    table: box(table),
    tableHead: box(table && table.querySelector('thead')),
    firstRow: box(firstData),
    rowClasses: rows.map(r => r.className),
    scrollWidth: document.documentElement.scrollWidth,
    links: Array.from(document.querySelectorAll('a[href]')).map(a => (
      {href: a.getAttribute('href'), url: a.href})),
    ids: Array.from(document.querySelectorAll('[id]')).map(e => e.id),
    names: Array.from(document.querySelectorAll('a[name]')).map(e => e.name),
    sources: Array.from(document.querySelectorAll('[src]')).map(e => e.getAttribute('src')),
    stylesheets: Array.from(document.querySelectorAll('link[href]')).map(
      e => e.getAttribute('href')),
  };
})()"""


@pytest.fixture(scope="module", params=["pass", "fail"])
def loaded(request: pytest.FixtureRequest, chromium: Chromium,
           qualifications: dict[str, Path]) -> dict[str, Any]:
    """What Chromium saw of one report: page facts, console errors, requested URLs."""
    report = qualifications[request.param] / "report.html"
    chromium.load(report.resolve().as_uri(), width=WIDTH, height=HEIGHT)
    facts = chromium.evaluate(_PAGE_FACTS)
    facts.update(kind=request.param, report=report, errors=chromium.console_errors(),
                 requested=chromium.requested_urls())
    return facts


def test_page_loads_without_console_errors(loaded: dict[str, Any]) -> None:
    assert loaded["title"], "the page did not load"
    assert loaded["errors"] == []


def broken_links(facts: dict[str, Any], report: Path) -> list[str]:
    """Links of the page that leave it, or whose file or anchor does not exist."""
    ids = set(facts["ids"]) | set(facts["names"])
    broken = []
    for link in facts["links"]:
        href, url = link["href"], urlparse(link["url"])
        if url.scheme not in ("file", ""):
            broken.append(f"{href}: not internal ({url.scheme})")
            continue
        if href.startswith("#"):
            if unquote(href[1:]) not in ids:
                broken.append(f"{href}: no such anchor")
            continue
        target = Path(unquote(url.path))
        if not target.exists() or not target.resolve().is_relative_to(report.parent.resolve()):
            broken.append(f"{href}: {target} missing or outside the qualification directory")
        elif url.fragment and target.resolve() == report.resolve() \
                and unquote(url.fragment) not in ids:
            broken.append(f"{href}: no such anchor")
    return broken


def outside_requests(facts: dict[str, Any], report: Path) -> list[str]:
    """URLs the page fetched other than itself and ``data:`` URIs."""
    own = report.resolve().as_uri()
    return [u for u in facts["requested"] if not (u.startswith("data:") or u == own)]


def test_every_internal_link_and_anchor_resolves(loaded: dict[str, Any]) -> None:
    assert loaded["links"], "the report has links"
    assert broken_links(loaded, loaded["report"]) == []


def test_nothing_is_fetched_from_outside(loaded: dict[str, Any]) -> None:
    assert outside_requests(loaded, loaded["report"]) == []
    assert all(s.startswith("data:") for s in loaded["sources"]), loaded["sources"]
    assert loaded["stylesheets"] == []                  # the style is inline


def test_verdict_and_measurements_in_the_first_screenful(loaded: dict[str, Any]) -> None:
    verdict, head, first = loaded["verdict"], loaded["tableHead"], loaded["firstRow"]
    assert verdict and verdict["shown"] and verdict["top"] >= 0 and verdict["bottom"] <= HEIGHT
    assert head and head["shown"] and head["bottom"] <= HEIGHT, head
    assert first and first["shown"] and first["bottom"] <= HEIGHT, first
    assert loaded["scrollWidth"] <= WIDTH, "no horizontal scrolling at 1366 px"


def test_failing_report_says_fail_first_with_failing_rows_first(
        chromium: Chromium, qualifications: dict[str, Path]) -> None:
    chromium.load((qualifications["fail"] / "report.html").resolve().as_uri(),
                  width=WIDTH, height=HEIGHT)
    facts = chromium.evaluate(_PAGE_FACTS)
    assert facts["verdictWord"].strip() == "FAIL"
    assert facts["verdict"]["top"] < facts["table"]["top"]
    statuses = [c.split("m-", 1)[1].split()[0] for c in facts["rowClasses"] if "m-" in c]
    assert statuses and statuses[0] in ("fail", "error")
    rank = {"fail": 0, "error": 1, "marginal": 2, "pass": 3, "info": 4}
    failing = [i for i, s in enumerate(statuses) if rank[s] <= 1]
    assert failing == list(range(len(failing))), statuses


def test_passing_report_says_pass(chromium: Chromium, qualifications: dict[str, Path]) -> None:
    chromium.load((qualifications["pass"] / "report.html").resolve().as_uri(),
                  width=WIDTH, height=HEIGHT)
    assert chromium.evaluate(_PAGE_FACTS)["verdictWord"].strip() == "PASS"


def test_the_checks_catch_a_broken_page(chromium: Chromium, tmp_path: Path) -> None:
    """The same checks on a page with each defect: they must find all of them."""
    page = tmp_path / "bad.html"
    page.write_text("""<!DOCTYPE html><html><head><title>bad</title></head><body>
<a href="#nowhere">anchor</a> <a href="runs/missing/bus.log">file</a>
<a href="https://example.invalid/">outside</a>
<img src="http://127.0.0.1:9/pixel.png" alt="">
<script>console.error("boom"); undefined_function();</script>
</body></html>""")
    chromium.load(page.as_uri(), width=WIDTH, height=HEIGHT)
    facts = chromium.evaluate(_PAGE_FACTS)
    facts["requested"] = chromium.requested_urls()
    errors = chromium.console_errors()
    assert any("boom" in e for e in errors)
    assert any("undefined_function" in e for e in errors)
    assert "http://127.0.0.1:9/pixel.png" in outside_requests(facts, page)
    broken = " ".join(broken_links(facts, page))
    assert "#nowhere" in broken and "runs/missing/bus.log" in broken
    assert "https://example.invalid/" in broken
    assert not all(s.startswith("data:") for s in facts["sources"])
