"""README.md is a landing page (issue 43): short, the two commands first, the details on the
documentation's pages. It had grown to 198 lines, a third of them campaign tables, which the
reference-qualification page now carries."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
REFERENCE_QUALIFICATION = ROOT / "docs" / "guide" / "reference-qualification.md"
MAX_LINES = 120


def test_the_readme_is_a_landing_page() -> None:
    text = README.read_text(encoding="utf-8")
    lines = text.splitlines()
    assert len(lines) <= MAX_LINES, f"README.md has {len(lines)} lines (at most {MAX_LINES})"
    sections = re.findall(r"^## (.+)$", text, re.M)
    assert sections[0] == "Two commands", sections
    first = text.index("## Two commands")
    assert text.index("bash scripts/qualify.sh") > first
    assert text.index("bash scripts/test.sh") > text.index("bash scripts/qualify.sh")
    # no campaign table on the landing page: they live on the reference-qualification page
    assert not [line for line in lines if line.startswith("| rig | seeds |")]


def test_the_campaign_tables_are_on_the_reference_qualification_page() -> None:
    page = REFERENCE_QUALIFICATION.read_text(encoding="utf-8")
    section = page[page.index("## How often the reference controllers qualify"):
                   page.index("## Measuring it")]
    tables = [line for line in section.splitlines() if line.startswith("| rig | seeds |")]
    assert len(tables) == 2, tables
    for seeds in ("9600000-9600298", "8700000-8700299", "9500000-9500299", "9200000-9200299"):
        assert seeds in section, seeds
    readme = README.read_text(encoding="utf-8")
    assert "reference-qualification.md#how-often-the-reference-controllers-qualify" in readme
