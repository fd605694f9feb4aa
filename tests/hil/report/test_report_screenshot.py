"""The report in a real browser: headless Chromium renders it to a PNG that is not blank."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[3] / "scripts" / "screenshot_report.sh"


@pytest.mark.skipif(shutil.which("chromium") is None, reason="chromium not installed")
def test_chromium_renders_the_report(qual_page: tuple[Path, str], tmp_path: Path) -> None:
    import matplotlib.image

    qual_dir, _ = qual_page
    out = tmp_path / "report.png"
    proc = subprocess.run(["bash", str(SCRIPT), str(qual_dir), str(out)], capture_output=True,
                          text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(out.resolve())
    image = matplotlib.image.imread(out)[..., :3]
    assert image.shape[:2] == (4000, 1280)
    inked = (image < 0.9).any(axis=2)
    assert inked.mean() > 0.02, "the screenshot is (nearly) blank"
    assert image.std() > 0.05
    # the FAIL verdict box (#c62828) is drawn near the top of the page
    red = (np.abs(image[:500] - np.array([0xC6, 0x28, 0x28]) / 255).max(axis=2) < 0.06)
    assert red.sum() > 2000
