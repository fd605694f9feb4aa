"""Build a firmware DUT on first use and cache it.

The cache key is a hash of the build command and of every file under the profile's
``build.sources``: a changed source rebuilds, an unchanged tree reuses the entry. Builds of the
same key are serialized with a lock file, so parallel qualifications build once. The build's
output goes to ``build.log`` in the entry; a failed build raises :class:`DutError` with its
tail.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import subprocess
import sys
import time
from pathlib import Path

from hil.dut.base import DutError
from hil.dut.profile import DutProfile
from hil.errors import ConfigError

PROJECT_ROOT = Path(__file__).resolve().parents[2]
SKIP_PARTS = {"build", ".git", "__pycache__"}


def cache_root() -> Path:
    explicit = os.environ.get("AGRIHIL_CACHE")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "agrihil"


def profile_dir(profile: DutProfile) -> Path:
    return profile.path.parent if profile.path else Path.cwd()


def resolve(path: str, profile: DutProfile) -> Path:
    """Relative paths in a profile are relative to the project root (where the sources are)."""
    p = Path(expand(path, profile))
    return p if p.is_absolute() else PROJECT_ROOT / p


def source_hash(profile: DutProfile) -> str:
    assert profile.build is not None
    digest = hashlib.sha256()
    digest.update("\0".join(profile.build.command).encode())
    for src in sorted(profile.build.sources):
        root = resolve(src, profile)
        if not root.exists():
            raise ConfigError(f"build source {src!r} does not exist ({root})",
                              path=str(profile.path), key="build.sources")
        files = [root] if root.is_file() else sorted(
            p for p in root.rglob("*") if p.is_file() and not SKIP_PARTS & set(
                p.relative_to(root).parts))
        for f in files:
            digest.update(str(f.relative_to(PROJECT_ROOT) if f.is_relative_to(PROJECT_ROOT)
                              else f).encode())
            digest.update(f.read_bytes())
    return digest.hexdigest()[:16]


def build_dir(profile: DutProfile) -> Path:
    return cache_root() / "builds" / f"{profile.name}-{source_hash(profile)}"


def expand(arg: str, profile: DutProfile, *, bus: str = "", build: Path | None = None) -> str:
    values = {"python": sys.executable, "root": str(PROJECT_ROOT),
              "profile_dir": str(profile_dir(profile)), "bus": bus,
              "build_dir": str(build) if build else ""}
    for key, value in values.items():
        arg = arg.replace("{" + key + "}", value)
    return arg


def ensure_built(profile: DutProfile) -> dict[str, object]:
    """Build ``profile`` unless its cache entry is complete; returns what the record keeps."""
    if profile.build is None:
        return {}
    target = build_dir(profile)
    target.mkdir(parents=True, exist_ok=True)
    done = target / ".built"
    with (target / ".lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        artifacts = [resolve(expand(a, profile, build=target), profile)
                     for a in profile.build.artifacts]
        if done.exists() and all(a.exists() for a in artifacts):
            return {"build_dir": str(target), "cached": True, "build_s": 0.0}
        command = [expand(a, profile, build=target) for a in profile.build.command]
        log_path = target / "build.log"
        t0 = time.perf_counter()
        with log_path.open("w") as log:
            try:
                proc = subprocess.run(command, cwd=PROJECT_ROOT, stdout=log,
                                      stderr=subprocess.STDOUT, timeout=profile.build.timeout_s,
                                      check=False)
            except FileNotFoundError as exc:
                raise DutError(f"{profile.path}: [build.command] cannot run "
                               f"{command[0]!r}: {exc}") from exc
            except subprocess.TimeoutExpired as exc:
                raise DutError(f"{profile.path}: build timed out after "
                               f"{profile.build.timeout_s:.0f} s; log: {log_path}") from exc
        elapsed = time.perf_counter() - t0
        if proc.returncode != 0:
            tail = log_path.read_text(errors="replace")[-2000:]
            raise DutError(f"{profile.path}: build failed (exit {proc.returncode}); "
                           f"log: {log_path}\n{tail}")
        missing = [str(a) for a in artifacts if not a.exists()]
        if missing:
            raise DutError(f"{profile.path}: [build.artifacts] the build did not produce "
                           f"{', '.join(missing)}")
        done.write_text(f"{elapsed:.3f}\n")
        return {"build_dir": str(target), "cached": False, "build_s": round(elapsed, 3)}
