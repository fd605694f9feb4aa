"""The documentation site builds with warnings as errors (issue 19).

A broken cross-reference, a missing page in a toctree, a docstring that does not parse, or a
generated table (CLI, measurement catalogue, plugin options) that no longer matches the code fails
the test run, the same way ``bash scripts/docs.sh`` fails.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_docs_build_without_warnings(tmp_path: Path) -> None:
    out = tmp_path / "html"
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-E", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(REPO / "docs"), str(out)],
        capture_output=True, text=True, timeout=600, cwd=REPO)
    assert proc.returncode == 0, f"sphinx-build failed:\n{proc.stderr[-5000:]}"
    catalogue = (out / "reference" / "measurements.html").read_text(encoding="utf-8")
    from hil.limits import MEASUREMENTS

    missing = [name for name in MEASUREMENTS if name not in catalogue]
    assert not missing, f"measurements missing from the generated catalogue: {missing}"
    cli = (out / "reference" / "cli.html").read_text(encoding="utf-8")
    headings = set(re.findall(r"<h\d[^>]*>([^<]+)<", cli))
    from hil.cli.main import SUBCOMMANDS

    for module in SUBCOMMANDS:
        command = module.rsplit(".", 1)[-1]
        assert command in headings, f"the CLI reference lacks `hil {command}`: {headings}"


def test_catalogue_states_the_bus_defaults_the_checks_apply() -> None:
    """The catalogue's words for the bus checks' default limits are the numbers the checks use
    (issue 31.4: the page must say what will fail)."""
    from hil.conformance import measure
    from hil.limits import MEASUREMENTS, default_limit_text

    cycle, heartbeat = measure.CYCLE_TOLERANCE_PCT, measure.HEARTBEAT_TOLERANCE_PCT
    assert default_limit_text("bus.share") == f"<= {measure.BUS_SHARE_PCT:g}"
    assert default_limit_text("bus.cycle_time.median").startswith(
        f">= -{cycle:g}, <= {cycle:g} ")
    assert default_limit_text("bus.heartbeat.period").startswith(
        f">= -{heartbeat:g}, <= {heartbeat:g} ")
    assert default_limit_text("bus.cycle_time.outside_band").startswith(
        f"<= {measure.OUTSIDE_BAND_PCT:g} in lockstep")
    assert f"+ {cycle:g} %" in default_limit_text("bus.sync_latency.p99")
    # a limit in numbers and one in words would be two definitions
    both = [n for n, s in MEASUREMENTS.items()
            if s.default_rule and (s.low is not None or s.high is not None)]
    assert not both, f"a default limit both in numbers and in words: {both}"
