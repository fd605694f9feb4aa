"""Boot the user-mode Linux guest once and run the ``kernel_can`` tests inside it.

This is the host side of the kernel CAN tests: the default test run runs the short set
(``kernel_can and not slow``); the ``slow`` set (qualification subsets, a real-time run, a
physical ECU on vcan) runs with ``-m slow``. Where the guest cannot start (no ``linux.uml``,
not root, not Debian) the test is skipped with the reason and the command that installs what is
missing.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests.kernel.conftest import ROOT

SCRIPT = ROOT / "scripts" / "kernel-can.sh"


def _guest_or_skip() -> None:
    if os.environ.get("AGRIHIL_IN_GUEST"):
        pytest.skip("already inside the guest")
    done = subprocess.run(["bash", str(SCRIPT), "--check"], capture_output=True, text=True,
                          timeout=60)
    if done.returncode != 0:
        pytest.skip(done.stderr.strip() or f"kernel-can.sh --check exit {done.returncode}")


def _prebuild_firmware(cache: Path) -> None:
    """Build the firmware on the host into the guest's cache (faster than inside)."""
    env = {**os.environ, "AGRIHIL_CACHE": str(cache / "agrihil")}
    code = ("from hil.dut.build import ensure_built; from hil.dut.profile import load_profile;"
            "import sys; [ensure_built(load_profile(p)) for p in sys.argv[1:]]")
    profiles = [str(p) for p in sorted((ROOT / "dut_profiles").glob("*-firmware.toml"))]
    subprocess.run([sys.executable, "-c", code, *profiles], cwd=ROOT, env=env, check=True,
                   capture_output=True, timeout=900)


def _run_in_guest(marker: str, tmp_path: Path) -> ET.Element:
    _guest_or_skip()
    cache = Path(os.environ.get("AGRIHIL_GUEST_CACHE",
                                Path.home() / ".cache" / "agrihil-guest"))
    _prebuild_firmware(cache)
    results = tmp_path / "guest"
    junit = results / "junit.xml"
    t0 = time.monotonic()
    done = subprocess.run(
        ["bash", str(SCRIPT), "--results", str(results), "--cache", str(cache), "--",
         "python", "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", marker,
         "--durations=0", f"--junitxml={junit}", "tests/kernel"],
        capture_output=True, text=True, timeout=1800, cwd=ROOT)
    wall = time.monotonic() - t0
    print(done.stdout[-6000:])
    print(f"guest: {wall:.1f} s including boot")
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    suite = ET.parse(junit).getroot()
    suite = suite if suite.tag == "testsuite" else suite[0]
    return suite


def _collected(marker: str) -> int:
    """How many tests of tests/kernel the marker selects (collected on the host)."""
    done = subprocess.run([sys.executable, "-m", "pytest", "--co", "-q", "-p", "no:cacheprovider",
                           "-m", marker, "tests/kernel"], capture_output=True, text=True,
                          timeout=120, cwd=ROOT)
    return sum(1 for line in done.stdout.splitlines() if "::" in line)


def test_kernel_can_tests_pass_inside_the_guest(tmp_path: Path) -> None:
    suite = _run_in_guest("kernel_can and not slow", tmp_path)
    # every test inside ran: none may be skipped (inside, the kernel has vcan)
    assert int(suite.get("tests", 0)) == _collected("kernel_can and not slow") >= 9
    assert int(suite.get("failures", 0)) == 0 and int(suite.get("errors", 0)) == 0
    assert int(suite.get("skipped", 0)) == 0, "a kernel_can test skipped inside the guest"


@pytest.mark.slow
def test_long_kernel_can_tests_pass_inside_the_guest(tmp_path: Path) -> None:
    suite = _run_in_guest("kernel_can and slow", tmp_path)
    assert int(suite.get("tests", 0)) == _collected("kernel_can and slow") >= 7
    assert int(suite.get("failures", 0)) == 0 and int(suite.get("errors", 0)) == 0
    assert int(suite.get("skipped", 0)) == 0, "a kernel_can test skipped inside the guest"


def test_a_checkout_under_tmp_runs_in_the_guest(tmp_path: Path) -> None:
    """The guest mounts a fresh tmpfs on /tmp: a checkout there (here: reached through a
    symlink under /tmp, as the script sees its own path) is mounted again from the host."""
    _guest_or_skip()
    link = Path("/tmp") / f"agrihil-checkout-{os.getpid()}-{tmp_path.name}"
    link.symlink_to(ROOT)
    try:
        cache = Path(os.environ.get("AGRIHIL_GUEST_CACHE",
                                    Path.home() / ".cache" / "agrihil-guest"))
        done = subprocess.run(
            ["bash", str(link / "scripts" / "kernel-can.sh"), "--results",
             str(tmp_path / "guest"), "--cache", str(cache), "--", "python", "-c",
             "import os, hil; print('in', os.getcwd(), 'hil from', hil.__file__)"],
            capture_output=True, text=True, timeout=600, cwd=tmp_path)
    finally:
        link.unlink()
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert f"in {link} hil from {link}/hil/__init__.py" in done.stdout, done.stdout[-3000:]
