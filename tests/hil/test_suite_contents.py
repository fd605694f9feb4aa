"""What each ``--suite`` runs on each rig is what docs/guide/suites.md says (issue 43: ``full``
was described as "the papers' three repeats", and on the depth rig it runs two field runs).

Collects each rig's suites as ``hil qualify`` hands them to pytest and reads every test's
``hil_suite`` marker (slow: one collection per rig, ~10 s each).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hil.cli.suites import suite_location

ROOT = Path(__file__).resolve().parents[2]

PLUGIN = '''
import json, os
import pytest

@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config, items):
    out = {}
    for item in items:
        mark = item.get_closest_marker("hil_suite")
        out.setdefault(mark.args[0] if mark else "(every)", []).append(item.name)
    with open(os.environ["SUITES_OUT"], "w") as f:
        json.dump(out, f)
'''


def collected(rig: str, tmp_path: Path) -> dict[str, list[str]]:
    directory, ini = suite_location(rig)
    (tmp_path / "suites_dump.py").write_text(PLUGIN, encoding="utf-8")
    out = tmp_path / f"{rig}.json"
    env = {**os.environ, "SUITES_OUT": str(out),
           "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    done = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-c",
                           str(ini), "-p", "suites_dump", "--hil-suite", "all",
                           str(directory)], cwd=ini.parent, env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    return json.loads(out.read_text(encoding="utf-8"))


@pytest.mark.slow
def test_full_adds_the_papers_repeats_on_the_fertilizer_rig(tmp_path: Path) -> None:
    suites = collected("fertilizer", tmp_path)
    full = sorted(suites["full"])
    assert len(full) == 12
    assert all(name.endswith(("-2]", "-3]")) for name in full)      # repeats 2 and 3
    assert {name.split("[")[0] for name in full} == {"test_bench_accuracy",
                                                     "test_field_accuracy"}
    assert sum(name.startswith("test_bench_accuracy") for name in suites["fast"]) == 3


@pytest.mark.slow
def test_full_adds_two_field_runs_on_the_depth_rig(tmp_path: Path) -> None:
    suites = collected("sowing_depth", tmp_path)
    assert sorted(suites["full"]) == ["test_depth_field[1-3]", "test_depth_field[5-7]"]
    assert "test_depth_field[3-5]" in suites["fast"]
    page = (ROOT / "docs" / "guide" / "suites.md").read_text(encoding="utf-8")
    assert "1-3 and 5-7 km/h**: two runs, no repeats" in page
    assert "**second and third repeats**" in page
