"""The profile schema page is generated from the loader's code (issue 43): every table and key
the loader accepts is listed, each with its meaning."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

from hil.dut.profile import DutProfile, load_profile
from hil.dut.schema import markdown, schema

ROOT = Path(__file__).resolve().parents[3]


def test_every_table_of_the_loader_is_listed_with_every_key() -> None:
    tables = {t.name: t for t in schema()}
    fields = [f.name for f in dataclasses.fields(DutProfile) if f.name not in ("path", "sha256")]
    assert sorted(tables) == sorted("rig" if f == "rig_config" else f for f in fields)
    assert [k.name for k in tables["launch"].keys][:2] == ["command", "lockstep_args"]
    assert {"low", "high", "marginal", "when", "reason"} <= {k.name for k in
                                                             tables["limits"].keys}
    assert tables["dut"].required and not tables["build"].required
    node = next(k for k in tables["wiring"].keys if k.name == "node_id")
    assert node.required and node.type == "integer"
    period = next(k for k in tables["timing"].keys if k.name == "control_period_ms")
    assert "60000 ms" in period.valid


def test_every_key_says_what_it_means() -> None:
    """A key added to a table's dataclass without a line in its docstring fails here, so the
    page never lists a key without its meaning."""
    silent = [f"[{t.name}] {k.name}" for t in schema() for k in t.keys
              if not k.meaning and not k.valid]
    assert not silent, f"keys without a description in their dataclass's docstring: {silent}"


def test_the_page_is_markdown_with_a_table_per_section() -> None:
    text = "\n".join(markdown())
    assert "**`[dut]`** (required)" in text and "| `reason` | string |" in text
    assert "``" not in text and ":class:" not in text          # reST turned into Markdown
    page = (ROOT / "docs" / "reference" / "profile-schema.md").read_text(encoding="utf-8")
    assert "```{profile-schema}" in page


def test_a_profile_using_only_listed_keys_loads() -> None:
    """The shipped reference profile's keys are all on the page."""
    path = ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-firmware.toml"
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    tables = {t.name: {k.name for k in t.keys} for t in schema()}
    for table, body in data.items():
        if table in ("parameters", "rig", "limits"):
            continue
        assert set(body) <= tables[table], (table, set(body) - tables[table])
    load_profile(path)
