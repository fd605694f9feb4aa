"""Qualify two builds of one controller and compare their control measurements.

"Built against another database, the reference controller gives the same control
measurements to the last digit" (issue 28) is checked for four builds (RC-400 in Python and C,
DP-200 in Python and C); each qualifies the reference and the build with ``hil qualify`` and
compares the values here.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

__all__ = ["control_measurements", "qualified_measurements"]

#: a measurement's key: its name and its conditions without the run (a run's name carries
#: the scenario file, which differs between two profiles' runs of the same scenario)
Key = tuple[str, str]


def control_measurements(record: Path, prefix: str) -> dict[Key, float | None]:
    """The values of ``record``'s measurements whose name starts with ``prefix``
    (``flow.``, ``depth.``: the control measurements, bus conformance left out)."""
    out: dict[Key, float | None] = {}
    for m in json.loads(record.read_text(encoding="utf-8"))["measurements"]:
        if m["name"].startswith(prefix):
            conditions = {k: v for k, v in (m.get("conditions") or {}).items() if k != "run"}
            out[(m["name"], json.dumps(conditions, sort_keys=True))] = m["value"]
    return out


def qualified_measurements(hil: str, profile: Path, out: Path, *, bus: str, prefix: str,
                           cwd: Path, suites: str = "fast,robustness") -> dict[Key, float | None]:
    """``hil qualify profile`` (lockstep, the default seed) into ``out``, which must pass;
    its control measurements."""
    done = subprocess.run([hil, "qualify", str(profile), "--bus", bus, "--suite", suites,
                           "--out", str(out), "--quiet"], cwd=cwd, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    return control_measurements(out / "record.json", prefix)
