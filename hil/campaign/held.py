"""A profile held to another profile's ``[campaign]`` requirement.

A must-fail profile is a reference controller with one defect; it states no requirement of its
own, but what it is judged against in a release is what the reference states. This writes a
copy of the profile (same file name, so its ``[dut] name`` still matches) with the reference's
``[campaign]`` table appended, for the early-decision benchmark
(``benchmarks/bench_campaign_decision.py``) and its slow test.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from hil.errors import ConfigError


def campaign_table(reference: Path) -> str:
    """The ``[campaign]`` table of ``reference`` as TOML text (its keys, in file order)."""
    data = tomllib.loads(reference.read_text(encoding="utf-8"))
    table = data.get("campaign")
    if not isinstance(table, dict):
        raise ConfigError("states no [campaign] requirement", path=str(reference),
                          key="campaign")
    lines = [f"{key} = {value!r}" for key, value in table.items()]
    return "[campaign]\n" + "\n".join(lines) + "\n"


def held_to(profile: Path, reference: Path, into: Path) -> Path:
    """Write ``profile`` into the directory ``into`` with ``reference``'s ``[campaign]``
    table appended; returns the copy's path. A profile stating its own is refused."""
    text = profile.read_text(encoding="utf-8")
    if tomllib.loads(text).get("campaign") is not None:
        raise ConfigError("already states a [campaign] requirement", path=str(profile),
                          key="campaign")
    into.mkdir(parents=True, exist_ok=True)
    copy = into / profile.name
    note = f"# held to the requirement of {reference.name}\n"
    copy.write_text(re.sub(r"\n*$", "\n\n", text) + note + campaign_table(reference),
                    encoding="utf-8")
    return copy
