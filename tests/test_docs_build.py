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
