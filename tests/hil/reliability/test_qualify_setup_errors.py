"""Setup errors of ``hil qualify`` are exit 2 naming the option or file, never an
interruption and never three failed tests; a full disk names the path and leaves no staging
directory behind (issue 30)."""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.helpers.hil_forkserver import Done, HilForkServer
from tests.hil.reliability.conftest import dying_profile_text

ROOT = Path(__file__).resolve().parents[3]
PROFILE = ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml"
PREVIOUS = {"schema": "agrihil.qualification/1", "run_id": "old", "verdict": "pass",
            "dut": {"name": "x"}, "measurements": []}


def _hil(server: HilForkServer, *argv: str) -> Done:
    """``python -m hil ARGV`` in a process of its own, forked by the ``hil_forked`` server."""
    return server.run(list(argv), ROOT, timeout_s=300)


def _previous(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "record.json").write_text(json.dumps(PREVIOUS))


def _untouched(out: Path) -> None:
    assert json.loads((out / "record.json").read_text()) == PREVIOUS
    assert sorted(p.name for p in out.iterdir()) == ["record.json"]


@pytest.mark.parametrize("expression", ["step or (touch x", "and", "   "])
def test_a_malformed_k_is_exit_2_naming_k(tmp_path: Path, expression: str,
                                          hil_forked: HilForkServer) -> None:
    out = tmp_path / "q"
    _previous(out)
    done = _hil(hil_forked, "qualify", str(PROFILE), "--bus", "inline", "--out", str(out),
                "-k", expression)
    assert done.returncode == 2, done.stderr
    assert "[-k]" in done.stderr and "interrupted" not in done.stderr.lower()
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    _untouched(out)


def test_a_non_executable_dut_command_is_refused_up_front(tmp_path: Path,
                                                          hil_forked: HilForkServer) -> None:
    binary = tmp_path / "dut-fw"
    binary.write_text("#!/bin/sh\nexit 0\n")
    binary.chmod(0o644)                                       # chmod -x
    profile = tmp_path / "toy.toml"
    profile.write_text(dying_profile_text("toy", "x").replace(
        'command = ["{python}", ', f'command = ["{binary}", "--bus", "{{bus}}"] # ', 1))
    out = tmp_path / "q"
    _previous(out)
    done = _hil(hil_forked, "qualify", str(profile), "--out", str(out), "--suite", "fast")
    assert done.returncode == 2, done.stderr
    line = done.stderr.strip().splitlines()[-1]
    assert str(binary) in line and "launch.command" in line and "execut" in line, line
    assert "FAILED" not in done.stdout
    _untouched(out)


@contextlib.contextmanager
def _tiny_disk(where: Path, size: str = "300k") -> Iterator[Path]:
    where.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs",
                              str(where)], capture_output=True, text=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here (needs root): {mounted.stderr.strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


def test_a_full_disk_names_the_path_and_cleans_the_staging(tmp_path: Path,
                                                           hil_forked: HilForkServer) -> None:
    if os.geteuid() != 0:
        pytest.skip("mounting a 300 kB tmpfs as --out needs root")
    with _tiny_disk(tmp_path / "disk") as disk:
        out = disk / "q"
        _previous(out)
        done = _hil(hil_forked, "qualify", str(PROFILE), "--bus", "inline", "--suite", "fast",
                    "-k", "flow_step", "--quiet", "--out", str(out))
        assert done.returncode == 2, done.stderr
        line = done.stderr.strip().splitlines()[-1]
        assert "No space left on device" in line and str(out) in line, line
        left = sorted(p.name for p in out.iterdir())
        assert not [n for n in left if n.startswith(".qualify-")], left
        # the previous record is kept; record.json says the new one did not finish
        assert json.loads((out / "record.previous.json").read_text()) == PREVIOUS
        assert json.loads((out / "record.json").read_text())["verdict"] != "pass"
