"""The worked example's rig (docs/examples/own-rig-motor-meter) copied and built for a test:
its StateSpace FMU compiled from the Reference-FMUs sources with CMake, as a user would."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
EXAMPLE = ROOT / "docs" / "examples" / "own-rig-motor-meter"
THIRD_PARTY = ROOT / "firmware" / "fmu" / "third_party"


def build_fmu(source: Path, build: Path) -> Path:
    """Configure and build the example's CMake project; the FMU it made."""
    subprocess.run(["cmake", "-S", str(source), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
                    f"-DTHIRD_PARTY={THIRD_PARTY}"], check=True, capture_output=True)
    subprocess.run(["cmake", "--build", str(build)], check=True, capture_output=True)
    fmu = build / "StateSpace.fmu"
    assert fmu.is_file()
    return fmu


def example_copy(dest: Path) -> Path:
    """The example copied to ``dest`` with its FMU built in ``dest/build``; the rig file."""
    shutil.copytree(EXAMPLE, dest, ignore=shutil.ignore_patterns("build", "__pycache__"))
    build_fmu(dest, dest / "build")
    return dest / "motor-meter.rig.toml"
