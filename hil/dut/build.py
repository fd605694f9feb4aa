"""Build a firmware DUT on first use and cache it.

The cache key is a hash of the build command and of every file under the profile's
``build.sources``: a changed source rebuilds, an unchanged tree reuses the entry. Builds of the
same key are serialized with a lock file, so parallel qualifications build once. The build's
output goes to ``build.log`` in the entry; a failed build raises :class:`DutError` with its
tail.

Traceability: what :func:`ensure_built` returns goes into the record (and the report's device
block): the SHA-256 of the source set the cache is keyed on (the key is its first 16 hex
digits), the SHA-256 and size of every artifact, and the C compiler CMake used (its
``--version`` first line, found through ``CMakeCache.txt`` in the entry). The build id itself
comes from the profile's ``[dut] build_id`` or the command line (:func:`with_build_id`).
"""

from __future__ import annotations

import dataclasses
import fcntl
import hashlib
import re
import subprocess
import time
from pathlib import Path

from hil.dut.base import DutError
from hil.dut.code_identity import digest_sources, expand_placeholders
from hil.dut.paths import PROJECT_ROOT, build_entry
from hil.dut.profile import DutProfile
from hil.errors import ConfigError


def profile_dir(profile: DutProfile) -> Path:
    """The directory of the profile's file, absolute (the working directory without one).

    A relative profile path is taken from the working directory, where the user named it: left
    relative, ``{profile_dir}`` would later be joined to the project root instead.
    """
    return profile.path.resolve().parent if profile.path else Path.cwd()


def resolve(path: str, profile: DutProfile) -> Path:
    """Relative paths in a profile are relative to the project root (where the sources are)."""
    p = Path(expand(path, profile))
    return p if p.is_absolute() else PROJECT_ROOT / p


def missing_sources(profile: DutProfile) -> list[tuple[str, Path]]:
    """The ``build.sources`` that do not exist, each with where it was looked for."""
    if profile.build is None:
        return []
    return [(src, root) for src in profile.build.sources
            if not (root := resolve(src, profile)).exists()]


def source_hash(profile: DutProfile) -> str:
    """The build cache key: the first 16 hex digits of :func:`source_sha256`."""
    return source_sha256(profile)[:16]


def source_sha256(profile: DutProfile) -> str:
    """SHA-256 of the build command and of every file under the profile's ``build.sources``.

    Each file adds its path (relative to the project root) and its bytes, in sorted order;
    ``build``, ``.git`` and ``__pycache__`` directories are left out.

    Raises
    ------
    ConfigError
        A build source does not exist.
    """
    assert profile.build is not None
    roots = []
    for src in sorted(profile.build.sources):
        root = resolve(src, profile)
        if not root.exists():
            raise ConfigError(f"build source {src!r} does not exist ({root})",
                              path=str(profile.path), key="build.sources")
        roots.append(root)
    return digest_sources(profile.build.command, roots)


def build_dir(profile: DutProfile, digest: str | None = None) -> Path:
    """The cache entry of ``profile`` (``digest``: its :func:`source_sha256`, if known).

    Keyed by what the build is, not by whose: the digest covers the build command and every
    source byte, so profiles that build the same tree with the same command (the rigs'
    reference firmware, the examples built from ``firmware/``) share one build instead of
    each making its own (a full firmware build: ~17 s on a loaded 2-core host).
    """
    return build_entry(digest or source_sha256(profile))


def expand(arg: str, profile: DutProfile, *, bus: str = "", build: Path | None = None) -> str:
    """``arg`` with the placeholders of a profile's command expanded.

    The placeholders are ``{python}``, ``{root}``, ``{profile_dir}``, ``{bus}`` and
    ``{build_dir}``; ``{params}`` is not expanded here: it stands for several arguments (the
    process runner expands it).

    Parameters
    ----------
    arg : str
        One argument of a profile's command.
    profile : DutProfile
        The profile it comes from.
    bus : str, optional
        The bus spec for ``{bus}``.
    build : Path, optional
        The build cache entry for ``{build_dir}``.

    Returns
    -------
    str
        The argument with the placeholders replaced (an empty string for a missing bus or build).
    """
    return expand_placeholders(arg, profile_dir=profile_dir(profile), bus=bus, build=build)


#: a build id is one line of printable text (a commit hash, a CI job's tag)
_BUILD_ID = re.compile(r"[\x21-\x7e][\x20-\x7e]{0,199}")


def with_build_id(profile: DutProfile, build_id: str | None) -> DutProfile:
    """``profile`` with ``[dut] build_id`` set to ``build_id`` (None: unchanged).

    Raises
    ------
    ConfigError
        If ``build_id`` is empty, longer than 200 characters or not printable ASCII.
    """
    if build_id is None:
        return profile
    if not _BUILD_ID.fullmatch(build_id) or build_id != build_id.strip():
        raise ConfigError(f"--build-id must be 1-200 printable ASCII characters without "
                          f"leading or trailing spaces, got {build_id!r}", key="build_id")
    return dataclasses.replace(profile, dut=dataclasses.replace(profile.dut,
                                                                build_id=build_id))


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes (read in 1 MiB blocks)."""
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def compiler_version(build: Path) -> str:
    """First line of ``--version`` of the C (else C++) compiler CMake configured in ``build``.

    Read from its ``CMakeCache.txt``; "" when there is none or the compiler does not answer.
    """
    cache = build / "CMakeCache.txt"
    if not cache.is_file():
        return ""
    text = cache.read_text(errors="replace")
    for key in ("CMAKE_C_COMPILER", "CMAKE_CXX_COMPILER"):
        match = re.search(rf"^{key}:[A-Z]+=(.+)$", text, re.MULTILINE)
        if not match or not match.group(1).strip():
            continue
        try:
            proc = subprocess.run([match.group(1).strip(), "--version"], capture_output=True,
                                  text=True, timeout=30, check=False)
        except (OSError, subprocess.TimeoutExpired):
            continue
        lines = proc.stdout.strip().splitlines()
        if proc.returncode == 0 and lines:
            return lines[0].strip()
    return ""


def _traceability(digest: str, target: Path, artifacts: list[Path]) -> dict[str, object]:
    """What identifies the binary: source set, artifacts, compiler (kept in the entry)."""
    compiler_file = target / ".compiler"
    if compiler_file.exists():
        compiler = compiler_file.read_text().strip()
    else:
        compiler = compiler_version(target)
        compiler_file.write_text(compiler + "\n")
    return {"source_sha256": digest,
            "artifacts": [{"path": str(a.relative_to(target) if a.is_relative_to(target)
                                       else a),
                           "sha256": file_sha256(a), "bytes": a.stat().st_size}
                          for a in artifacts],
            "compiler": compiler}


def ensure_built(profile: DutProfile) -> dict[str, object]:
    """Build ``profile`` unless its cache entry is complete; return what the record keeps.

    Parameters
    ----------
    profile : DutProfile
        A firmware profile (others have nothing to build).

    Returns
    -------
    dict
        The entry's directory, whether it was cached, the build's duration, and the
        traceability facts (source SHA-256, artifacts with SHA-256 and size, compiler); empty for
        a profile without ``[build]``.

    Raises
    ------
    DutError
        The build command cannot run, times out, fails (with the tail of its log) or does not
        produce every artifact.
    ConfigError
        A build source does not exist.
    """
    if profile.build is None:
        return {}
    digest = source_sha256(profile)
    target = build_dir(profile, digest)
    target.mkdir(parents=True, exist_ok=True)
    done = target / ".built"
    with (target / ".lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        artifacts = [resolve(expand(a, profile, build=target), profile)
                     for a in profile.build.artifacts]
        if done.exists() and all(a.exists() for a in artifacts):
            return {"build_dir": str(target), "cached": True, "build_s": 0.0,
                    **_traceability(digest, target, artifacts)}
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
        (target / ".compiler").unlink(missing_ok=True)
        facts = _traceability(digest, target, artifacts)
        done.write_text(f"{elapsed:.3f}\n")
        return {"build_dir": str(target), "cached": False, "build_s": round(elapsed, 3),
                **facts}
