"""``hil ARGV`` in a process of its own, forked from a server that imported ``hil`` once.

Why: the CLI fuzz test runs each bad argv as a separate ``hil`` process with a time limit (a
refused option must not start a server that serves for ever), and the docs test runs each
``hil`` line of the docs as a reader types it; ~85 % of such a short process's CPU is the
interpreter and ``hil``'s imports (~0.45 s of ~0.5 s, measured), paid again for every command.
A child forked from a fresh interpreter that has imported ``hil`` and the libraries its
subcommands use is still a ``hil`` process of its own: its own session, cwd, the server's
environment, ``sys.argv`` as the ``hil`` script sets it, stdin from ``/dev/null``, stdout and
stderr to files, ``main``'s return value its exit status, an uncaught exception printed as a
traceback and exit 1, as the ``hil`` script and ``python -m hil`` do.

The server is a plain interpreter, not the test process (a fork of pytest would inherit its
logging handlers, warning filters and threads), with the ``sys.path[0]`` and ``sys.argv[0]``
of the command it stands for: the ``hil`` script (``script=True``: the script's directory,
as a shell's ``hil`` has) or ``python -m hil`` run in the repository (its root). It is not
:mod:`multiprocessing`'s fork server, whose one server per process is shared with (and
configured by) ``hil.campaign.forked`` in the same test worker.

Protocol, one JSON line each way: request ``{"argv", "cwd", "env", "stdout", "stderr"}``
(``env``: variables set in the child on top of the server's environment; one a preloaded
module reads when it is imported keeps the server's value), answers ``{"pid"}`` at once and
``{"status"}`` (``waitstatus_to_exitcode``) when the child ends.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import subprocess
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
#: imported by the server before it forks: ``hil``'s command line and what its subcommands
#: import when they start (the libraries of the buses and databases, pytest, the rigs, the
#: gate's statistics, the report), so that no child pays for them (speed only: a module not
#: listed is imported by the child that needs it)
PRELOAD = ("hil.cli.main", "hil.cli.run", "hil.cli.qualify", "hil.cli.gate", "hil.cli.report",
           "hil.cli.bus", "hil.cli.campaign", "hil.cli.profile", "hil.cli.isobus",
           "hil.gate.comparison", "hil.gate.summary", "hil.report.page", "hil.pytest_plugin",
           "hil.rig.scenario", "hil.dut.factory", "hil.campaign.stats",
           "plant_emulators.fertilizer.rig", "pytest", "can", "cantools", "canopen")


def _child(request: dict[str, Any]) -> int:
    """In the forked child: become ``hil`` with the request's argv, cwd and output files."""
    os.setsid()
    os.chdir(str(request["cwd"]))
    os.environ.update(request.get("env") or {})
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    for fd, key in ((1, "stdout"), (2, "stderr")):
        target = os.open(str(request[key]), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(target, fd)
        os.close(target)
    from hil.cli.main import main

    argv = [str(a) for a in request["argv"]]
    sys.argv = [sys.argv[0], *argv]                 # the record's "command"
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except BaseException:                              # as the interpreter reports it
        traceback.print_exc()
        code = 1
    sys.stdout.flush()
    sys.stderr.flush()
    return int(code)


def serve(argv0: str, path0: str) -> None:
    """The server's loop: fork a child per request line, report its pid and its status.
    ``argv0`` and ``path0`` are the children's ``sys.argv[0]`` and ``sys.path[0]``."""
    import importlib

    sys.argv = [argv0]
    sys.path[0] = path0
    for name in PRELOAD:
        importlib.import_module(name)

    for line in sys.stdin:
        request = json.loads(line)
        pid = os.fork()
        if pid == 0:
            code = 1
            try:
                code = _child(request)
            finally:
                os._exit(code)
        print(json.dumps({"pid": pid}), flush=True)
        _, status = os.waitpid(pid, 0)
        print(json.dumps({"status": os.waitstatus_to_exitcode(status)}), flush=True)


@dataclass
class Done:
    returncode: int
    stdout: str
    stderr: str


class HilTimeout(Exception):
    """The child still ran after the time limit (it and its process group were killed)."""


class HilForkServer:
    """The client: ``run(argv, cwd, timeout_s)`` as ``subprocess.run`` of the ``hil`` script
    (``script``) or of ``python -m hil``, with the environment ``env`` (default: this
    process's) that the server starts with."""

    def __init__(self, scratch: Path, env: dict[str, str] | None = None, *,
                 script: bool = False) -> None:
        self.scratch = scratch
        self.count = 0
        self.buffer = b""
        hil = Path(sys.executable).with_name("hil")
        argv0, path0 = ((hil, hil.parent) if script else (ROOT / "hil" / "__main__.py", ROOT))
        self.proc = subprocess.Popen(
            [sys.executable, "-c", "import sys; from tests.helpers.hil_forkserver import serve; "
             "serve(*sys.argv[1:])", str(argv0), str(path0)],
            cwd=ROOT, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, bufsize=0)

    def _answer(self, timeout_s: float) -> dict[str, int] | None:
        """The server's next answer line, or None when none came within ``timeout_s``."""
        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        deadline = time.monotonic() + timeout_s
        while b"\n" not in self.buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                return None
            chunk = os.read(fd, 4096)
            assert chunk, f"the hil fork server died (exit {self.proc.poll()})"
            self.buffer += chunk
        line, _, self.buffer = self.buffer.partition(b"\n")
        answer: dict[str, int] = json.loads(line)
        return answer

    def run(self, argv: list[str], cwd: Path, timeout_s: float,
            env: dict[str, str] | None = None) -> Done:
        assert self.proc.stdin is not None
        self.count += 1
        out, err = (self.scratch / f"{self.count}.{name}" for name in ("out", "err"))
        request = {"argv": argv, "cwd": str(cwd), "env": env or {}, "stdout": str(out),
                   "stderr": str(err)}
        self.proc.stdin.write(json.dumps(request).encode() + b"\n")
        started = self._answer(60)
        assert started is not None, "the hil fork server did not fork within 60 s"
        ended = self._answer(timeout_s)
        if ended is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(started["pid"], signal.SIGKILL)
            self._answer(60)
            raise HilTimeout(f"{argv} still ran after {timeout_s} s")
        return Done(ended["status"], out.read_text(errors="replace"),
                    err.read_text(errors="replace"))

    def close(self) -> None:
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def __enter__(self) -> HilForkServer:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
