"""Traceability of a firmware DUT (#20.4): what the build records and the report shows.

The build cache entry yields the SHA-256 of the source set the cache is keyed on, of every
artifact, and the compiler CMake configured; the build id comes from the profile or
``--build-id``; the report's device block shows them all.
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hil.dut.build import compiler_version, ensure_built, source_sha256, with_build_id
from hil.dut.profile import load_profile
from hil.errors import ConfigError

from .conftest import STEP_RUN

ROOT = Path(__file__).resolve().parents[3]
FIRMWARE_PROFILE = ROOT / "dut_profiles" / "fertilizer-open-loop-firmware.toml"


def _profile(tmp_path: Path, sources: Path, build_id: str = "") -> Path:
    """The firmware profile with a build that copies ``sources``/main.c to the artifact."""
    text = FIRMWARE_PROFILE.read_text()
    text = re.sub(r"\[build\]\n(.+\n)+?artifacts = .+\n",
                  "[build]\ncommand = [\"sh\", \"-c\", \"cp " + str(sources / "main.c")
                  + " {build_dir}/fw.bin\"]\nsources = [\"" + str(sources) + "\"]\n"
                  "artifacts = [\"{build_dir}/fw.bin\"]\n", text)
    if build_id:
        text = text.replace('version = "1.0.0"\n', f'version = "1.0.0"\nbuild_id = "{build_id}"\n')
    path = tmp_path / FIRMWARE_PROFILE.name
    path.write_text(text)
    return path


@pytest.fixture
def sources(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("AGRIHIL_CACHE", str(tmp_path / "cache"))
    src = tmp_path / "src"
    src.mkdir()
    (src / "main.c").write_text("int main(void) { return 0; }\n")
    return src


def test_build_records_source_and_artifact_hashes(tmp_path: Path, sources: Path) -> None:
    profile = load_profile(_profile(tmp_path, sources))
    first = ensure_built(profile)
    assert first["cached"] is False
    assert re.fullmatch(r"[0-9a-f]{64}", str(first["source_sha256"]))
    assert str(first["build_dir"]).endswith(str(first["source_sha256"])[:16])
    artifact = Path(str(first["build_dir"])) / "fw.bin"
    assert first["artifacts"] == [{"path": "fw.bin", "bytes": artifact.stat().st_size,
                                   "sha256": hashlib.sha256(artifact.read_bytes()).hexdigest()}]
    assert first["compiler"] == ""                   # no CMake here: said, not guessed
    again = ensure_built(profile)
    assert again["cached"] is True
    assert {k: again[k] for k in ("source_sha256", "artifacts", "compiler")} == {
        k: first[k] for k in ("source_sha256", "artifacts", "compiler")}
    (sources / "main.c").write_text("int main(void) { return 1; }\n")
    changed = ensure_built(profile)
    assert changed["source_sha256"] != first["source_sha256"]
    assert changed["artifacts"][0]["sha256"] != first["artifacts"][0]["sha256"]  # type: ignore[index]
    assert source_sha256(profile) == changed["source_sha256"]


def test_compiler_version_from_the_cmake_cache(tmp_path: Path) -> None:
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler on PATH (Debian: apt-get install gcc)")
    (tmp_path / "CMakeCache.txt").write_text(f"CMAKE_C_COMPILER:FILEPATH={cc}\n")
    expected = subprocess.run([cc, "--version"], capture_output=True, text=True,
                              check=True).stdout.splitlines()[0].strip()
    assert compiler_version(tmp_path) == expected != ""
    assert compiler_version(tmp_path / "nowhere") == ""


def test_build_id_from_profile_or_command_line(tmp_path: Path, sources: Path) -> None:
    profile = load_profile(_profile(tmp_path, sources, build_id="v1.0-rc2"))
    assert profile.identity()["build_id"] == "v1.0-rc2"
    ci = with_build_id(profile, "3f2a9c1b7d10e4f5a6b7c8d9e0f1a2b3c4d5e6f7")
    assert ci.identity()["build_id"] == "3f2a9c1b7d10e4f5a6b7c8d9e0f1a2b3c4d5e6f7"
    assert ci.identity()["profile_sha256"] == profile.identity()["profile_sha256"]
    assert with_build_id(profile, None) is profile
    for bad in ("", " lead", "two\nlines", "x" * 201):
        with pytest.raises(ConfigError, match="build-id"):
            with_build_id(profile, bad)


def test_cli_passes_the_build_id_to_the_suites(tmp_path: Path, sources: Path) -> None:
    from hil.cli.main import build_parser
    from hil.cli.qualify import pytest_args

    args = build_parser().parse_args(["qualify", str(FIRMWARE_PROFILE), "--build-id", "abc123"])
    argv = pytest_args(args, tmp_path, "fertilizer")
    assert argv[argv.index("--hil-build-id") + 1] == "abc123"
    bad = subprocess.run([sys.executable, "-m", "hil", "qualify", str(FIRMWARE_PROFILE),
                          "--build-id", "", "--out", str(tmp_path / "q")],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2
    assert "build-id" in bad.stderr and "Traceback" not in bad.stderr
    assert not (tmp_path / "q" / "record.json").exists()


def _identity(qual: Path) -> str:
    from hil.report import write_html

    page = write_html(qual).read_text(encoding="utf-8")
    identity = page[page.index('<section id="identity">'):]
    return identity[:identity.index("</section>")]


def test_report_device_block_shows_the_build(make_qual_dir: Callable[..., Path],
                                             base_record: dict[str, Any]) -> None:
    build = {"build_dir": "/cache/builds/fw-0123456789abcdef", "cached": True,
             "source_sha256": "0123456789abcdef" + "a" * 48,
             "artifacts": [{"path": "agrihil-fertilizer-fw", "sha256": "b" * 64,
                            "bytes": 123456}],
             "compiler": "cc (Debian 12.2.0-14) 12.2.0"}
    base_record["dut"] = {**base_record["dut"], "build_id": "3f2a9c1"}
    qual = make_qual_dir(base_record)
    assert "build sources sha256" not in _identity(qual)      # no run was built
    # the runs' records carry the build facts (the qualification record's dut is unchanged)
    run_record = qual / STEP_RUN / "record.json"
    data = json.loads(run_record.read_text())
    data.update(dut_build=build, dut_identity={"name": base_record["dut"]["name"]})
    run_record.write_text(json.dumps(data))
    identity = _identity(qual)
    for text in ("3f2a9c1", "0123456789abcdef" + "a" * 48, "b" * 64, "123,456 bytes",
                 "agrihil-fertilizer-fw", "cc (Debian 12.2.0-14) 12.2.0",
                 "from the build cache"):
        assert text in identity, text
