"""A DUT that runs as its own process (firmware host build or Python daemon).

Process hygiene is this module's job:

* the DUT gets its own process group, so everything it starts is stopped with it;
* its stdout and stderr go to files in the run directory (``dut.stdout.log``,
  ``dut.stderr.log``) and their tails go into the record;
* start-up waits until the DUT is on the bus (its CANopen boot-up frame, a line on stdout, or
  a delay) and fails with the DUT's own stderr when it exits or stays silent instead;
* :meth:`ProcessDut.check` turns a crash into :class:`DutError` with the exit status;
* :meth:`ProcessDut.stop` sends SIGTERM to the group, waits ``launch.stop_timeout_s``, then
  SIGKILLs the group and records that the DUT ignored SIGTERM. A finalizer does the same if
  the rig's process ends without calling ``stop``, so no process is left behind;
* the DUT dies with the rig's process even when that is SIGKILLed (``PR_SET_PDEATHSIG``), and
  the :mod:`~hil.lifetime` guardian follows its process tree, so what it started (even in
  a session of its own) is killed on stop or when the rig's process dies.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
import weakref
from pathlib import Path
from typing import IO, Any

from hil.bus import open_bus
from hil.dut.base import DutError, DutRunner, DutSetupError, DutStopped
from hil.dut.build import PROJECT_ROOT, expand
from hil.dut.profile import DutProfile
from hil.lifetime import die_with_parent, guardian

TAIL_CHARS = 4000


def _kill_group(pgid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, sig)


def _tail(path: Path | None) -> str:
    if path is None or not path.exists():
        return ""
    with path.open("rb") as fh:
        fh.seek(0, os.SEEK_END)
        size = fh.tell()
        fh.seek(max(0, size - TAIL_CHARS))
        return fh.read().decode(errors="replace")


def param_args(profile: DutProfile) -> list[str]:
    """The profile's parameters as arguments, ``--param key=value`` each (booleans true/false)."""
    out: list[str] = []
    for key, value in profile.parameters.items():
        text = ("true" if value else "false") if isinstance(value, bool) else str(value)
        out += ["--param", f"{key}={text}"]
    return out


def command_line(profile: DutProfile, *, bus: str, clock: str,
                 build: Path | None = None) -> list[str]:
    """The DUT's argv for ``bus`` and ``clock``, placeholders expanded."""
    launch = profile.launch
    extra = launch.lockstep_args if clock == "lockstep" else launch.realtime_args
    argv: list[str] = []
    for arg in (*launch.command, *extra):
        if arg == "{params}":
            argv += param_args(profile)
        else:
            argv.append(expand(arg, profile, bus=bus, build=build))
    return argv


class ProcessDut(DutRunner):
    """Runs a DUT as its own process (a firmware host build or a Python daemon).

    Parameters
    ----------
    profile : DutProfile
        The DUT's profile (its ``[launch]`` says how to start it and when it is ready).
    clock : str
        The run's clock; it picks ``lockstep_args`` or ``realtime_args``.
    log_dir : Path, optional
        Where ``dut.stdout.log`` and ``dut.stderr.log`` go (default: a temporary directory).
    build : Path, optional
        The build cache entry (``{build_dir}``) of a firmware DUT.
    """

    def __init__(self, profile: DutProfile, *, clock: str, log_dir: Path | None = None,
                 build: Path | None = None) -> None:
        self.profile = profile
        self.name = profile.name
        self.clock = clock
        self.log_dir = log_dir
        self.build = build
        self.proc: subprocess.Popen[bytes] | None = None
        self.argv: list[str] = []
        self.stdout_path: Path | None = None
        self.stderr_path: Path | None = None
        self._files: list[IO[bytes]] = []
        self._finalizer: weakref.finalize | None = None
        self._result: dict[str, Any] | None = None
        self.started_at = 0.0
        self.ready_s = 0.0
        self.starts = 0

    # --- start --------------------------------------------------------------------------------
    def start(self, bus_spec: str, env: dict[str, str] | None = None) -> None:
        """Start the process and return when it is ready (boot-up frame, stdout line or delay).

        Parameters
        ----------
        bus_spec : str
            The bus it joins (``{bus}`` and ``AGRIHIL_BUS``).
        env : dict of str to str, optional
            More environment from the rig (e.g. ``AGRIHIL_GNSS_PORT``).

        Raises
        ------
        DutSetupError
            The command cannot be executed.
        DutStopped
            It exited during start-up or was not ready within ``launch.ready_timeout_s`` (with the
            tail of its stderr); the process group is stopped.
        """
        launch = self.profile.launch
        # a restart (DutRunner.restart: stop, then start): stop() reports the new process,
        # whose output goes to its own files (dut.stdout.log, then dut.stdout.1.log, ...)
        self._result = None
        self.argv = command_line(self.profile, bus=bus_spec, clock=self.clock, build=self.build)
        proc_env = {**os.environ, **launch.env, **(env or {}), "AGRIHIL_BUS": bus_spec,
                    "AGRIHIL_CLOCK": self.clock, "PYTHONUNBUFFERED": "1"}
        log_dir = self.log_dir
        if log_dir is None:
            import tempfile
            log_dir = Path(tempfile.mkdtemp(prefix=f"agrihil-{self.name}-"))
        log_dir.mkdir(parents=True, exist_ok=True)
        suffix = "" if self.starts == 0 else f".{self.starts}"
        self.stdout_path = log_dir / f"dut.stdout{suffix}.log"
        self.stderr_path = log_dir / f"dut.stderr{suffix}.log"
        out = self.stdout_path.open("wb")
        err = self.stderr_path.open("wb")
        self._files = [out, err]
        # agrihil's socketcand client ends the software bus's 50 ms rawmode hold at once
        # (python-can's client needs the hold): the boot-up frame is seen ~50 ms sooner
        listen_spec = (f"{bus_spec},client=agrihil"
                       if bus_spec.startswith("socketcand:") and "client=" not in bus_spec
                       else bus_spec)
        listener = open_bus(listen_spec) if launch.ready == "bootup" else None
        try:
            self.started_at = time.monotonic()
            try:
                self.proc = subprocess.Popen(self.argv, cwd=PROJECT_ROOT, env=proc_env,
                                             stdin=subprocess.DEVNULL, stdout=out, stderr=err,
                                             start_new_session=True,
                                             preexec_fn=die_with_parent())
            except OSError as exc:
                raise DutSetupError(f"{self.profile.path}: [launch.command] cannot start "
                                    f"{self.argv[0]!r}: {exc}") from exc
            guardian().watch(self.proc.pid)
            self.starts += 1
            self._finalizer = weakref.finalize(self, _kill_group, self.proc.pid,
                                               signal.SIGKILL)
            self._await_ready(listener)
        except BaseException:
            self.stop()
            raise
        finally:
            if listener is not None:
                listener.shutdown()
        self.ready_s = time.monotonic() - self.started_at

    def _await_ready(self, listener: Any) -> None:
        launch = self.profile.launch
        deadline = time.monotonic() + launch.ready_timeout_s
        bootup_id = self.profile.wiring.heartbeat_id
        if launch.ready == "delay":
            end = time.monotonic() + launch.ready_delay_s
            while time.monotonic() < end:
                self._raise_if_exited("during start-up")
                time.sleep(0.02)
            return
        want = launch.ready.removeprefix("stdout:")
        while time.monotonic() < deadline:
            self._raise_if_exited("during start-up")
            if listener is not None:
                msg = listener.recv(0.05)
                if (msg is not None and msg.arbitration_id == bootup_id
                        and not msg.is_extended_id and bytes(msg.data[:1]) == b"\x00"):
                    return
            else:
                assert self.stdout_path is not None
                if want in self.stdout_path.read_text(errors="replace"):
                    return
                time.sleep(0.02)
        what = (f"its boot-up frame 0x{bootup_id:03X}" if listener is not None
                else f"{want!r} on its stdout")
        raise DutStopped(f"never came up: {self.name!r} did not show {what} within "
                         f"{launch.ready_timeout_s:g} s",
                         detail=f"stderr:\n{_tail(self.stderr_path)}")

    def _raise_if_exited(self, when: str) -> None:
        assert self.proc is not None
        code = self.proc.poll()
        if code is not None:
            raise DutStopped(f"exited with {self._describe(code, short=True)}"
                             + (f" {when}" if when else ""),
                             detail=f"stderr:\n{_tail(self.stderr_path)}")

    @staticmethod
    def _describe(code: int, *, short: bool = False) -> str:
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = str(-code)
            return name if short else f"signal {name}"
        return f"exit status {code}"

    # --- health -------------------------------------------------------------------------------
    def check(self) -> None:
        """Raise if the process has exited.

        Raises
        ------
        DutStopped
            It exited (with its exit status or signal, and the tail of its stderr).
        DutError
            It was never started.
        """
        if self.proc is None:
            raise DutError(f"DUT {self.name!r} was never started")
        self._raise_if_exited("")

    # --- stop ---------------------------------------------------------------------------------
    def stop(self, timeout: float | None = None) -> dict[str, Any]:
        """Stop the process group (SIGTERM, SIGKILL after the grace time) and escaped descendants.

        Safe to call twice (the second call returns the first's result).

        Parameters
        ----------
        timeout : float, optional
            The grace time after SIGTERM, in seconds (default: ``launch.stop_timeout_s``).

        Returns
        -------
        dict
            What the record keeps: argv, starts, start-up time, pid, exit status, whether it
            exited before the stop or ignored SIGTERM, descendants killed, the log files and their
            tails.
        """
        if self._result is not None and self.proc is None:
            return self._result
        grace = self.profile.launch.stop_timeout_s if timeout is None else timeout
        result: dict[str, Any] = {"name": self.name, "kind": self.profile.dut.kind,
                                  "argv": self.argv, "starts": self.starts,
                                  "ready_s": round(self.ready_s, 3)}
        proc = self.proc
        if proc is not None:
            guardian().scan(proc.pid)          # the tree as it is, while its root lives
            exited_before = proc.poll()
            ignored = False
            if exited_before is None:
                _kill_group(proc.pid, signal.SIGTERM)
                try:
                    proc.wait(grace)
                except subprocess.TimeoutExpired:
                    ignored = True
                    _kill_group(proc.pid, signal.SIGKILL)
                    proc.wait(5.0)
            # whatever the leader did, leave nothing of its group behind, nor of its tree
            # (a helper that escaped into a session of its own)
            _kill_group(proc.pid, signal.SIGKILL)
            escaped = guardian().kill_tree(proc.pid)
            if escaped:
                result["killed_descendants"] = escaped
            if self._finalizer is not None:
                self._finalizer.detach()
            code = proc.returncode
            result.update({
                "pid": proc.pid,
                "exit": self._describe(code) if code is not None else "unknown",
                "exit_code": code,
                "exited_before_stop": exited_before is not None,
                "ignored_sigterm": ignored,
            })
            self.proc = None
        for fh in self._files:
            fh.close()
        self._files = []
        result.update({"stdout": str(self.stdout_path) if self.stdout_path else None,
                       "stderr": str(self.stderr_path) if self.stderr_path else None,
                       "stdout_tail": _tail(self.stdout_path)[-1500:],
                       "stderr_tail": _tail(self.stderr_path)[-1500:]})
        self._result = result
        return result

    def identity(self) -> dict[str, Any]:
        """The profile's identity of the DUT (:meth:`DutProfile.identity`)."""
        return self.profile.identity()
