"""Fixtures of the browser tests: Chromium, and two real qualifications (a passing reference
DUT and a must-fail one), each a single short step test on the inline bus (~5 s each)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.helpers.session_shared import built_once

from .cdp import Chromium, find_chromium

ROOT = Path(__file__).resolve().parents[2]
#: (profile, exit status hil qualify must give)
QUALIFICATIONS = {
    "pass": ("dut_profiles/fertilizer-piecewise-pid-daemon.toml", 0),
    "fail": ("dut_profiles/must_fail/fertilizer-ignores-setpoint-daemon.toml", 1),
}
KEYWORD = "test_flow_step and 23"


@pytest.fixture(scope="session")
def chromium() -> Iterator[Chromium]:
    executable = find_chromium()
    if executable is None:
        pytest.skip("Chromium is not installed: apt-get install chromium "
                    "(scripts/setup.sh installs it when CI is set)")
    browser = Chromium(executable)
    try:
        yield browser
    finally:
        browser.close()


@pytest.fixture(scope="session")
def qualifications(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """kind → the qualification directory (record.json, report.html, runs/); made once per
    test session, whichever xdist worker needs them first (the tests only read them)."""
    with built_once(tmp_path_factory, "browser-qual") as (root, built):
        out = {kind: root / kind for kind in QUALIFICATIONS}
        if built:
            return out
        for kind, (profile, expected) in QUALIFICATIONS.items():
            proc = subprocess.run([sys.executable, "-m", "hil", "qualify", str(ROOT / profile),
                                   "--bus", "inline", "--suite", "fast", "-k", KEYWORD,
                                   "--out", str(out[kind]), "--quiet"],
                                  cwd=ROOT, capture_output=True, text=True, timeout=300)
            assert proc.returncode == expected, proc.stderr[-3000:]
            assert (out[kind] / "report.html").is_file()
        return out
