"""``scripts/setup.sh`` installs system packages only when asked: with ``--system-packages``,
or as root with apt when ``CI`` is set; never silently otherwise.

apt-get, dpkg-query, id, sudo, python, locale and localedef are stand-ins on PATH that log
their calls, so the test neither needs root nor touches the machine."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
STUB = """#!/bin/sh
echo "$(basename "$0") $*" >> "{log}"
{body}
"""


def _setup(tmp_path: Path, *args: str, uid: int = 0, ci: str | None = None,
           installed: tuple[str, ...] = ("kmod",), sudo: bool = True
           ) -> tuple[int, str, list[str]]:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir(exist_ok=True)
    log = tmp_path / "calls.log"
    log.write_text("")
    status = "install ok installed"
    bodies = {
        "apt-get": "exit 0",
        "dpkg-query": "for p in " + " ".join(installed)
                      + f'; do [ "$p" = "$3" ] && {{ printf "{status}"; exit 0; }}; done; exit 1',
        "id": f'[ "$1" = "-u" ] && echo {uid} || /usr/bin/id "$@"',
        "python": "exit 0",
        "sudo": 'exec "$@"',
        "locale": 'echo C; echo POSIX',       # no de_DE: asc2log's locale is made
        "localedef": "exit 0",
    }
    for name, body in bodies.items():
        if name == "sudo" and not sudo:
            continue
        path = bin_dir / name
        path.write_text(STUB.format(log=log, body=body))
        path.chmod(0o755)
    env = {"PATH": f"{bin_dir}:/usr/bin:/bin", "AGRIHIL_NO_VENV": "1", "HOME": str(tmp_path)}
    if ci is not None:
        env["CI"] = ci
    done = subprocess.run(["bash", str(ROOT / "scripts" / "setup.sh"), *args], env=env,
                          capture_output=True, text=True, timeout=60)
    calls = [line for line in log.read_text().splitlines()
             if line.startswith(("apt-get", "sudo", "localedef"))]
    return done.returncode, done.stderr, calls


def _installs(calls: list[str]) -> list[str]:
    return [c for c in calls if c.startswith("apt-get install")]


def test_nothing_is_installed_silently(tmp_path: Path) -> None:
    code, stderr, calls = _setup(tmp_path, uid=0, ci=None)
    assert code == 0 and calls == []
    assert "not installed: chromium user-mode-linux iproute2 can-utils locales" in stderr
    assert "--system-packages" in stderr


def test_ci_as_root_installs_what_is_missing(tmp_path: Path) -> None:
    code, _stderr, calls = _setup(tmp_path, uid=0, ci="true")
    assert code == 0
    assert _installs(calls) == ["apt-get install -y -q --no-install-recommends "
                                "chromium user-mode-linux iproute2 can-utils locales"]
    # asc2log reads ASC dates through the de_DE locale (tests/hil/record/test_buslog_time.py)
    assert calls[-1] == "localedef -i de_DE -f ISO-8859-1 de_DE"


def test_ci_without_root_does_not_install(tmp_path: Path) -> None:
    code, _stderr, calls = _setup(tmp_path, uid=1000, ci="true")
    assert code == 0 and calls == []


@pytest.mark.parametrize("uid", [0, 1000])
def test_the_flag_installs_as_root_or_through_sudo(uid: int, tmp_path: Path) -> None:
    code, _stderr, calls = _setup(tmp_path, "--system-packages", uid=uid)
    assert code == 0 and len(_installs(calls)) == 1
    assert any(c.startswith("sudo ") for c in calls) == (uid != 0)
    assert calls[-1].endswith("localedef -i de_DE -f ISO-8859-1 de_DE")


def test_the_flag_without_root_or_sudo_fails_clearly(tmp_path: Path) -> None:
    code, stderr, calls = _setup(tmp_path, "--system-packages", uid=1000, sudo=False)
    assert code != 0 and _installs(calls) == []
    assert "needs root" in stderr


def test_nothing_missing_installs_nothing(tmp_path: Path) -> None:
    everything = ("chromium", "user-mode-linux", "kmod", "iproute2", "can-utils", "locales")
    code, stderr, calls = _setup(tmp_path, "--system-packages", installed=everything)
    assert code == 0 and _installs(calls) == [] and "not installed" not in stderr


def test_an_unknown_argument_is_refused(tmp_path: Path) -> None:
    code, stderr, _ = _setup(tmp_path, "--sytem-packages")
    assert code == 2 and "unknown argument '--sytem-packages'" in stderr


def test_ci_run_is_still_the_readme_test_command() -> None:
    text = (ROOT / ".ci" / "run").read_text()
    assert text.rstrip().splitlines()[-1] == "exec bash scripts/test.sh"
    assert os.access(ROOT / "scripts" / "kernel-can.sh", os.R_OK)
