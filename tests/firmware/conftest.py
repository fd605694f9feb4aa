"""Fixtures for the firmware tests: a cached host build of firmware/, and a started app.

The build goes to ``$AGRIHIL_CACHE/builds/firmware-pytest-<hash of firmware/>`` (default cache
``~/.cache/agrihil``), so an unchanged tree is built once; the tests are skipped, with the
reason, only when cmake or a C compiler is missing.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import pytest

from hil.bus import open_bus
from hil.dut.base import DutError, DutRunner

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
APPS = ("agrihil-fertilizer-fw", "agrihil-depth-fw")


def _source_hash() -> str:
    digest = hashlib.sha256()
    for path in sorted(FIRMWARE.rglob("*")):
        rel = path.relative_to(FIRMWARE)
        if path.is_file() and not rel.parts[0].startswith("build"):
            digest.update(str(rel).encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _cache_root() -> Path:
    explicit = os.environ.get("AGRIHIL_CACHE")
    if explicit:
        return Path(explicit)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "agrihil"


def _build(build_dir: Path) -> None:
    log = build_dir / "build.log"
    with log.open("w") as out:
        for cmd in (["cmake", "-S", str(FIRMWARE), "-B", str(build_dir),
                     "-DCMAKE_BUILD_TYPE=Release", "-DBUILD_TESTING=OFF"],
                    ["cmake", "--build", str(build_dir), "-j2", "--target", *APPS]):
            if subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT,
                              timeout=300).returncode != 0:
                raise RuntimeError(f"firmware build failed ({' '.join(cmd)}):\n"
                                   f"{log.read_text()[-3000:]}")


@pytest.fixture(scope="session")
def firmware_bin(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Directory holding the two firmware programs, built on first use."""
    if shutil.which("cmake") is None:
        pytest.skip("cmake is not installed: cannot build the firmware")
    if not any(shutil.which(cc) for cc in (os.environ.get("CC", "cc"), "cc", "gcc", "clang")):
        pytest.skip("no C compiler (cc, gcc or clang): cannot build the firmware")
    try:
        root = _cache_root() / "builds"
        root.mkdir(parents=True, exist_ok=True)
    except OSError:
        root = tmp_path_factory.mktemp("firmware-build")
    build_dir = root / f"firmware-pytest-{_source_hash()}"
    build_dir.mkdir(exist_ok=True)
    with (root / f"{build_dir.name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)     # parallel sessions build once
        if not all((build_dir / app).exists() for app in APPS):
            _build(build_dir)
    return build_dir


@dataclass
class App:
    """A running firmware program and a python-can client on its bus."""

    proc: subprocess.Popen[bytes]
    bus: can.BusABC
    stderr_path: Path

    def stderr(self) -> str:
        return self.stderr_path.read_text(errors="replace")

    def send(self, can_id: int, data: bytes = b"", *, extended: bool | None = None) -> None:
        self.bus.send(can.Message(arbitration_id=can_id, data=data,
                                  is_extended_id=can_id > 0x7FF if extended is None
                                  else extended))

    def collect(self, want: set[int], timeout: float = 2.0) -> dict[int, can.Message]:
        """Receive until a frame of every id in ``want`` came (latest kept per id)."""
        got: dict[int, can.Message] = {}
        deadline = time.monotonic() + timeout
        while not want <= set(got) and time.monotonic() < deadline:
            msg = self.bus.recv(max(0.0, deadline - time.monotonic()))
            if msg is not None:
                got[msg.arbitration_id] = msg
        missing = want - set(got)
        assert not missing, (f"no frame {', '.join(f'0x{i:X}' for i in sorted(missing))} "
                             f"within {timeout} s; app stderr:\n{self.stderr()}")
        return got

    def sync(self, want: set[int], timeout: float = 2.0) -> dict[int, can.Message]:
        """Send SYNC and collect the step's frames."""
        self.send(0x080)
        return self.collect(want, timeout)

    def drain(self, settle: float = 0.05) -> None:
        while self.bus.recv(settle) is not None:
            pass

    def terminate(self, sig: int = signal.SIGTERM, timeout: float = 3.0) -> tuple[int, float]:
        """Send ``sig``; return (exit status, seconds it took)."""
        t0 = time.monotonic()
        self.proc.send_signal(sig)
        code = self.proc.wait(timeout)
        return code, time.monotonic() - t0


@pytest.fixture
def start_app(firmware_bin: Path, tmp_path: Path) -> Iterator:
    """``start_app(name, spec, *args, env=..., bootup_id=...)``: start a firmware program on
    the bus ``spec`` and return an :class:`App` once its CANopen boot-up frame was seen."""
    started: list[App] = []

    def start(name: str, spec: str, *args: str, env: dict[str, str] | None = None,
              bootup_id: int) -> App:
        bus = open_bus(spec)     # listening before the app starts: its boot-up is not missed
        stderr_path = Path(tempfile.mkstemp(prefix=f"{name}-", suffix=".stderr",
                                            dir=tmp_path)[1])
        with stderr_path.open("wb") as err:
            proc = subprocess.Popen([str(firmware_bin / name), "--bus", spec, *args],
                                    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                    stderr=err, env={**os.environ, **(env or {})})
        app = App(proc, bus, stderr_path)
        started.append(app)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            msg = bus.recv(0.1)
            if (msg is not None and msg.arbitration_id == bootup_id
                    and bytes(msg.data) == b"\x00"):
                return app
            assert proc.poll() is None, f"{name} exited {proc.returncode}:\n{app.stderr()}"
        raise AssertionError(f"{name}: no boot-up frame 0x{bootup_id:X}:\n{app.stderr()}")

    yield start
    for app in started:
        if app.proc.poll() is None:
            app.proc.kill()
            app.proc.wait(5)
        app.bus.shutdown()


@pytest.fixture
def run_fw(firmware_bin: Path):
    """``run_fw(name, *args, env=...)``: run a firmware program to its end (for argument and
    start-up errors) and return the completed process (text output)."""

    def run(name: str, *args: str,
            env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
        return subprocess.run([str(firmware_bin / name), *args], capture_output=True,
                              text=True, timeout=10, env={**os.environ, **(env or {})})

    return run


class FirmwareDut(DutRunner):
    """Just enough of a process DUT for a rig run (hil/dut/process.py is the real one): start
    the program with the rig's bus and environment, wait for its boot-up, SIGTERM at the end."""

    def __init__(self, argv: list[str], bootup_id: int) -> None:
        self.argv = argv
        self.bootup_id = bootup_id
        self.proc: subprocess.Popen[bytes] | None = None
        self.name = Path(argv[0]).name
        self._stderr: Any = None

    def start(self, bus_spec: str, env: dict[str, str] | None = None) -> None:
        listener = open_bus(bus_spec)
        try:
            self._stderr = tempfile.TemporaryFile()  # noqa: SIM115 (closed in stop())
            self.proc = subprocess.Popen([*self.argv, "--bus", bus_spec],
                                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                         stderr=self._stderr,
                                         env={**os.environ, **(env or {})})
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline:
                msg = listener.recv(0.1)
                if msg is not None and msg.arbitration_id == self.bootup_id:
                    return
                self.check()
            raise DutError(f"{self.name} did not send its boot-up frame")
        finally:
            listener.shutdown()

    def stop(self, timeout: float = 5.0) -> dict[str, Any]:
        if self.proc is None:
            return {}
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self._stderr.seek(0)
        err = self._stderr.read().decode(errors="replace")
        self._stderr.close()
        result = {"name": self.name, "exit_code": self.proc.returncode, "stderr": err}
        self.proc = None
        return result

    def check(self) -> None:
        if self.proc is not None and self.proc.poll() is not None:
            raise DutError(f"{self.name} exited with status {self.proc.returncode}")


@pytest.fixture
def firmware_dut() -> type[FirmwareDut]:
    """The :class:`FirmwareDut` class (tests cannot import from conftest)."""
    return FirmwareDut
