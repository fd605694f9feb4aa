"""What identifies the code under test: the program a DUT's command runs, and its git state.

A profile's hash says how the DUT was set up, not what ran. The record therefore also names
the program itself (issue 43):

* a daemon: the file its ``launch.command`` runs: an executable, or for an interpreter
  (``{python}``, ``python3``, ``sh``, ``bash``) the script it is given, or the module of
  ``python -m module``; its SHA-256 and size;
* a firmware: the binary its build makes (the command's executable in the build cache entry),
  once built, and the SHA-256 of the source set it was built from;
* an in-process controller: the module file of ``launch.inprocess``;
* each, where its files are in a git work tree: the revision and whether the DUT's files
  differ from it (``dirty``: modified, staged or untracked files among them).

The user's ``build_id`` stays theirs. Paths are written relative to the project root, or to
their git work tree, so a record names no machine's directories where it need not.

This module takes plain values (the command, the paths), not a profile: the profile loader
calls it, and nothing here imports the loader.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.dut.paths import PROJECT_ROOT

#: interpreters whose program is the script or module they are given, not themselves
INTERPRETERS = ("python", "python3", "sh", "bash", "dash")
#: options of those interpreters that take the next argument as their value
_OPTIONS_WITH_VALUE = {"-W", "-X", "-Q"}


@dataclass(frozen=True)
class Program:
    """The file a command runs, or why it names none.

    ``path``: the file (which may not exist); None for inline code (``python -c``,
    ``sh -c``). ``what``: ``executable``, ``script`` or ``module NAME``. ``problem``: why it
    cannot be run (missing file, unknown module), empty when it can.
    """

    path: Path | None
    what: str
    problem: str = ""


def _is_interpreter(program: str) -> bool:
    name = Path(program).name
    return name in INTERPRETERS or (name.startswith("python") and
                                    name[6:].replace(".", "").isdigit())


def _module_file(module: str) -> tuple[Path | None, str]:
    """The file ``python -m module`` runs, or why there is none (without running it)."""
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError) as exc:
        return None, f"module {module!r} cannot be found: {exc}"
    if spec is None:
        return None, f"module {module!r} cannot be found"
    if spec.submodule_search_locations:      # a package: its __main__
        main = importlib.util.find_spec(f"{module}.__main__")
        if main is None or not main.origin:
            return None, f"package {module!r} has no __main__ module"
        return Path(main.origin), ""
    if not spec.origin or not Path(spec.origin).is_file():
        return None, f"module {module!r} is not a file"
    return Path(spec.origin), ""


def program_of(argv: Sequence[str], *, cwd: Path = PROJECT_ROOT) -> Program:
    """The file ``argv`` (placeholders expanded) runs.

    As a process DUT is started: in ``cwd`` (the project root), the executable looked up on
    ``PATH`` if it has no ``/``.
    """
    if not argv:
        return Program(None, "executable", "the command is empty")
    first = argv[0]
    executable = Path(first) if os.sep in first else (
        Path(found) if (found := shutil.which(first)) else None)
    if executable is None:
        return Program(None, "executable", f"{first!r} is not a command on PATH")
    if not executable.is_absolute():
        executable = cwd / executable
    if not _is_interpreter(first):
        problem = "" if executable.is_file() else f"{executable} does not exist"
        return Program(executable, "executable", problem)
    args = list(argv[1:])
    while args and args[0].startswith("-"):
        option = args.pop(0)
        if option in ("-c",):
            return Program(None, "inline code")
        if option == "-m" and args:
            path, problem = _module_file(args[0])
            return Program(path, f"module {args[0]}", problem)
        if option in _OPTIONS_WITH_VALUE and args:
            args.pop(0)
    if not args:
        return Program(None, "interpreter without a script",
                       f"{first} is given no script to run")
    script = Path(args[0])
    script = script if script.is_absolute() else cwd / script
    return Program(script, "script", "" if script.is_file() else f"{script} does not exist")


def shown(path: Path) -> str:
    """``path`` as a record writes it.

    Relative to the project root, else to its git work tree, else absolute.
    """
    resolved = path.resolve()
    if resolved.is_relative_to(PROJECT_ROOT):
        return str(resolved.relative_to(PROJECT_ROOT))
    top = _git_top(resolved.parent if resolved.is_file() else resolved)
    return str(resolved.relative_to(top)) if top else str(resolved)


@functools.lru_cache(maxsize=64)
def _file_digest(path: str, mtime_ns: int, size: int) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def file_facts(path: Path) -> dict[str, Any]:
    """``{"path", "sha256", "bytes"}`` of a file (hashed once per version of it)."""
    stat = path.stat()
    return {"path": shown(path), "sha256": _file_digest(str(path), stat.st_mtime_ns,
                                                         stat.st_size),
            "bytes": stat.st_size}


def _git(cwd: Path, *args: str) -> str | None:
    try:
        done = subprocess.run(["git", "-C", str(cwd), *args], capture_output=True, text=True,
                              timeout=20, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout if done.returncode == 0 else None


@functools.lru_cache(maxsize=64)
def _git_top(directory: Path) -> Path | None:
    out = _git(directory, "rev-parse", "--show-toplevel") if directory.is_dir() else None
    return Path(out.strip()) if out else None


def git_state(paths: Sequence[Path]) -> dict[str, Any] | None:
    """The git revision of ``paths`` and whether they differ from it.

    The work tree is the first path's; ``dirty`` when any of ``paths`` is modified, staged or
    untracked. None outside a work tree. Asked once per process and set of paths (a
    qualification names the code it started with; every run's record asks again).
    """
    state = _git_state(tuple(str(p.resolve()) for p in paths if p.exists()))
    return dict(state) if state is not None else None


@functools.lru_cache(maxsize=32)
def _git_state(resolved: tuple[str, ...]) -> dict[str, Any] | None:
    existing = [Path(p) for p in resolved]
    if not existing:
        return None
    first = existing[0] if existing[0].is_dir() else existing[0].parent
    top = _git_top(first)
    if top is None:
        return None
    revision = _git(top, "rev-parse", "HEAD")
    if revision is None:       # a work tree without a commit yet
        return {"revision": None, "dirty": True}
    inside = [str(p) for p in existing if p.is_relative_to(top)]
    status = _git(top, "status", "--porcelain", "--untracked-files=normal", "--", *inside)
    return {"revision": revision.strip(), "dirty": bool(status and status.strip())}


def _dut_files(program: Path) -> Path:
    """The files a program stands for.

    Its top-level Python package's directory (for a module of one: the modules it imports),
    else the file itself.
    """
    directory = program.parent
    if program.suffix != ".py" or not (directory / "__init__.py").is_file():
        return program
    while (directory.parent / "__init__.py").is_file():
        directory = directory.parent
    return directory


def code_identity(*, kind: str, argv: Sequence[str], inprocess: str = "",
                  sources: Sequence[Path] = (), source_sha256: str = "",
                  built: bool = True, shown_as: str = "",
                  fmu: Path | None = None) -> dict[str, Any]:
    """What identifies a DUT's code, for the record's ``dut.code``.

    Parameters
    ----------
    kind : str
        The profile's ``dut.kind``.
    argv : sequence of str
        The launch command, placeholders expanded (``{build_dir}`` to the build cache entry).
    inprocess : str, optional
        ``launch.inprocess`` (``module:factory``).
    sources : sequence of Path, optional
        A firmware's ``build.sources``, resolved: the DUT's files for its git state.
    source_sha256 : str, optional
        A firmware's source set's SHA-256 (its build cache key).
    built : bool, optional
        Whether the firmware's build cache entry is complete (its binary is hashed only then).
    shown_as : str, optional
        The program's path as the record writes it (a firmware's ``{build_dir}/name``: the
        cache entry is this machine's), instead of :func:`shown`.
    fmu : Path, optional
        An FMU DUT's file (``[fmu] path`` resolved): its program.

    Returns
    -------
    dict
        ``program`` (``path``, ``sha256``, ``bytes``, ``what``; for a firmware not built yet
        ``sha256`` is None), ``source_sha256`` (firmware), ``inprocess_module`` (its file's
        facts) and ``git`` (``revision``, ``dirty``) where known; empty for a physical ECU.
    """
    if kind == "physical":
        return {}
    out: dict[str, Any] = {}
    files: list[Path] = list(sources)
    if argv:
        program = program_of(argv)
        if program.path is not None and not program.problem and (kind != "firmware" or built):
            out["program"] = {**file_facts(program.path), "what": program.what}
            if shown_as:
                out["program"]["path"] = shown_as
            if kind != "firmware":
                files.append(_dut_files(program.path))
        elif program.path is not None:
            out["program"] = {"path": shown_as or shown(program.path), "sha256": None,
                              "what": program.what,
                              "note": "not built yet" if kind == "firmware" and not built
                              else program.problem}
        else:
            out["program"] = {"path": None, "sha256": None, "what": program.what}
    if fmu is not None:
        if fmu.is_file() and built:
            out["program"] = {**file_facts(fmu), "what": "fmu"}
            if shown_as:
                out["program"]["path"] = shown_as
            if not sources:
                files.append(fmu)
        else:
            out["program"] = {"path": shown_as or shown(fmu), "sha256": None, "what": "fmu",
                              "note": "not built yet" if not built else "missing"}
    if source_sha256:
        out["source_sha256"] = source_sha256
    if inprocess:
        module_file, problem = _module_file(inprocess.partition(":")[0])
        if module_file is not None and not problem:
            out["inprocess_module"] = file_facts(module_file)
            files.append(_dut_files(module_file))
    git = git_state(files)
    if git is not None:
        out["git"] = git
    return out


#: directories of a source tree left out of its hash
SKIP_PARTS = {"build", ".git", "__pycache__"}


@functools.lru_cache(maxsize=16)
def identity_digest(command: tuple[str, ...], roots: tuple[Path, ...]) -> str:
    """:func:`digest_sources`, once per process.

    What the record's identity names; the build itself always hashes afresh
    (:func:`hil.dut.build.source_sha256`).
    """
    return digest_sources(command, roots)


def digest_sources(command: Sequence[str], roots: Sequence[Path]) -> str:
    """SHA-256 of a build command and of every file under ``roots``.

    ``roots`` exist and come in the order given; each file adds its path (relative to the
    project root) and its bytes, in sorted order; ``build``, ``.git`` and ``__pycache__``
    directories are left out. The build cache's key (:func:`hil.dut.build.source_sha256`).
    """
    digest = hashlib.sha256()
    digest.update("\0".join(command).encode())
    for root in roots:
        files = [root] if root.is_file() else sorted(
            p for p in root.rglob("*") if p.is_file() and not SKIP_PARTS & set(
                p.relative_to(root).parts))
        for f in files:
            digest.update(str(f.relative_to(PROJECT_ROOT) if f.is_relative_to(PROJECT_ROOT)
                              else f).encode())
            digest.update(f.read_bytes())
    return digest.hexdigest()


def expand_placeholders(arg: str, *, profile_dir: Path, bus: str = "",
                        build: Path | None = None) -> str:
    """``arg`` with a profile command's placeholders replaced.

    ``{python}``, ``{root}``, ``{profile_dir}``, ``{bus}`` and ``{build_dir}`` (an empty
    string for a missing bus or build); ``{params}`` is left: it stands for several arguments.
    """
    values = {"python": sys.executable, "root": str(PROJECT_ROOT),
              "profile_dir": str(profile_dir), "bus": bus,
              "build_dir": str(build) if build else ""}
    for key, value in values.items():
        arg = arg.replace("{" + key + "}", value)
    return arg
