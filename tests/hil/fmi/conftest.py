"""Fixtures for the FMU tests: a cached build of firmware/fmu's probe FMUs (no firmware code:
a quick build; the reference FMUs are built by their profiles' [build]).

The build goes to ``$AGRIHIL_CACHE/builds/fmu-pytest-<hash of its sources>`` (default cache
``~/.cache/agrihil``), so an unchanged tree is built once; the tests are skipped, with the
reason, only when cmake or a C compiler is missing.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
FIRMWARE = ROOT / "firmware"
SOURCES = ("fmu/common", "fmu/lsbus_probe", "fmu/lsbus_probe_timed", "fmu/third_party",
           "fmu/CMakeLists.txt", "hal/hal_can.h")
TARGETS = ("agrihil-lsbus-probe", "agrihil-lsbus-probe-timed")


def _source_hash() -> str:
    digest = hashlib.sha256()
    for top in SOURCES:
        root = FIRMWARE / top
        for path in sorted(root.rglob("*")) if root.is_dir() else [root]:
            if path.is_file():
                digest.update(str(path.relative_to(FIRMWARE)).encode())
                digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _cache_root() -> Path:
    explicit = os.environ.get("AGRIHIL_CACHE")
    if explicit:
        return Path(explicit)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "agrihil"


def build_fmus(build_dir: Path) -> Path:
    """Build the probe FMUs into ``build_dir`` (once); return its ``fmus`` folder."""
    build_dir.mkdir(parents=True, exist_ok=True)
    done = build_dir / ".built"
    with (build_dir / ".lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            log = build_dir / "build.log"
            with log.open("w") as out:
                for cmd in (["cmake", "-S", str(FIRMWARE / "fmu"), "-B", str(build_dir),
                             "-DCMAKE_BUILD_TYPE=Release"],
                            ["cmake", "--build", str(build_dir), "-j2", "--target",
                             *TARGETS]):
                    if subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT,
                                      timeout=600).returncode != 0:
                        raise RuntimeError(f"FMU build failed ({' '.join(cmd)}):\n"
                                           f"{log.read_text()[-3000:]}")
            done.write_text("ok\n")
    return build_dir / "fmus"


@pytest.fixture(scope="session")
def fmus() -> Path:
    """The folder of the built FMUs (``<name>.fmu``)."""
    if shutil.which("cmake") is None or shutil.which("cc") is None:
        pytest.skip("cmake and a C compiler are needed to build the FMUs")
    return build_fmus(_cache_root() / "builds" / f"fmu-pytest-{_source_hash()}")
