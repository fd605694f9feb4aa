"""Argument helpers shared by subcommands, and the checks every option gets before a run.

The checks raise :class:`~hil.errors.ConfigError` naming the option, so ``hil`` exits 2 with
one line before anything starts (a bad option is never blamed on the DUT).
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
from pathlib import Path
from typing import Any

from hil.dut.factory import check_bus_for_dut, in_process_bus
from hil.errors import ConfigError
from hil.softbus.server import DEFAULT_PORT
from hil.validation import CLI_RANGES, help_with_range

#: seeds go to numpy's SeedSequence (any non-negative integer) and into records and baselines
#: as JSON/TOML integers (64-bit): 0 .. 2**63 - 1
SEED_MAX = 2**63 - 1

__all__ = ["SEED_MAX", "add_bus_clock", "add_host_port", "check_bus_for_dut", "check_keyword",
           "check_launchable", "check_log_path", "check_positive_seconds", "check_seed",
           "check_writable_file", "in_process_bus", "port_number", "prepare_out_dir"]


def add_host_port(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", default="127.0.0.1", help="address (default: 127.0.0.1)")
    parser.add_argument("--port", type=port_number, default=DEFAULT_PORT,
                        help=help_with_range("--port", f"TCP port (default: {DEFAULT_PORT}; "
                                                       f"0 picks a free one)"))


def add_bus_clock(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--bus", default="softbus",
                        help="bus spec: 'softbus' (start an embedded software bus, the default), "
                             "'virtual', 'socketcan:vcan0', 'socketcand:HOST:PORT/CH', "
                             "'<python-can interface>:<channel>,key=value', or 'inline' "
                             "(lockstep with an in-process controller: no threads, fastest)")
    parser.add_argument("--clock", choices=["lockstep", "realtime"], default="lockstep",
                        help="lockstep (virtual time, fast, deterministic) or realtime")


def port_number(text: str) -> int:
    """argparse type of a TCP port: an integer 0..65535 (0: pick a free one)."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{port} is out of range (0..65535; 0 picks a free "
                                         f"port)")
    return port


def check_seed(seed: int | None, option: str = "--seed") -> None:
    """Refuse a seed the seeding cannot take (negative, or beyond 64 bits)."""
    if seed is not None and not CLI_RANGES["--seed"].contains(seed):
        raise ConfigError(f"{seed} is not a seed: give an integer 0 .. 2**63-1", key=option)


def check_positive_seconds(value: float, option: str) -> None:
    """Refuse a duration that is not a finite number of seconds above zero."""
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(f"{value} is not a duration: give a finite number of seconds > 0",
                          key=option)


def prepare_out_dir(path: str | Path, option: str = "--out") -> Path:
    """Create the output directory ``path`` (or check it) and prove it writable.

    Raises :class:`ConfigError` when ``path`` is an existing file, cannot be created, or
    cannot be written.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{out} exists and is not a directory", key=option)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create {out}: {exc.strerror or exc}", key=option) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise ConfigError(f"{out} is not writable", key=option)
    return out


def check_writable_file(path: str | Path, option: str, *, make_dirs: bool = False) -> Path:
    """Refuse a file path that cannot be written: the path an existing directory, its
    directory missing (unless ``make_dirs``: then the nearest existing ancestor must be a
    writable directory), a file in the way, or no permission."""
    target = Path(path)
    if target.is_dir():
        raise ConfigError(f"{target} is a directory, not a file", key=option)
    parent = target.absolute().parent
    if make_dirs:
        while not parent.exists() and parent != parent.parent:
            parent = parent.parent
    if not parent.is_dir():
        why = "is a file" if parent.exists() else "does not exist"
        raise ConfigError(f"cannot write {target}: {parent} {why}", key=option)
    if not os.access(parent, os.W_OK | os.X_OK) or (target.exists()
                                                     and not os.access(target, os.W_OK)):
        raise ConfigError(f"cannot write {target}: permission denied", key=option)
    return target


def check_log_path(path: str | Path, option: str = "--log") -> Path:
    """Refuse a bus-log path whose extension python-can cannot write, naming those it can,
    and one that cannot be written."""
    import can

    writers = sorted(getattr(can.io.logger, "MESSAGE_WRITERS", {}) or {})
    target = Path(path)
    suffixes = [s.lower() for s in target.suffixes]
    known = [s for s in suffixes if s in writers]
    if writers and not known:
        raise ConfigError(f"{target}: python-can cannot write a {target.suffix or 'suffix-less'} "
                          f"log; use one of {', '.join(writers)}", key=option)
    return check_writable_file(target, option)


#: the rig commands' own bus words, not python-can specs
RIG_BUSES = ("softbus", "inline")


def check_bus_spec(spec: str, option: str = "--bus") -> None:
    """Refuse a bus spec that cannot name a bus before anything runs: a malformed spec, an
    unknown transport (naming those available), a socketcand address without a valid port."""
    from hil.bus import available_transports, parse_spec
    from hil.errors import BusSpecError

    if spec in RIG_BUSES:
        return
    try:
        parsed = parse_spec(spec)
    except BusSpecError as exc:
        raise ConfigError(str(exc), key=option) from exc
    known = available_transports()
    if parsed.transport not in known:
        raise ConfigError(f"{spec}: unknown bus transport {parsed.transport!r}; available: "
                          f"{', '.join([*RIG_BUSES, *known])}", key=option)
    if parsed.transport in ("socketcan", "socketcand") and not parsed.channel:
        example = ("socketcan:vcan0" if parsed.transport == "socketcan"
                   else "socketcand:HOST:PORT[/CH]")
        raise ConfigError(f"{spec}: {parsed.transport} needs a channel ({example})", key=option)
    if parsed.transport == "socketcand":
        address = parsed.channel.split("/", 1)[0]
        host, _, port = address.rpartition(":")
        if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
            raise ConfigError(f"{spec}: socketcand needs HOST:PORT with a port 1..65535 "
                              "(e.g. socketcand:127.0.0.1:29536/can0)", key=option)


def check_keyword(expression: str | None, option: str = "-k") -> None:
    """Refuse a ``-k`` expression pytest cannot parse, naming the option and the column.

    pytest would only say so once collection ran, as an error that reads like an interrupted
    run; its own parser (``_pytest.mark.expression``, the one ``-k`` uses: pytest has no
    public one) checks it before anything starts."""
    if expression is None:
        return
    from _pytest.mark.expression import Expression

    if not expression.strip():
        raise ConfigError("an empty expression selects nothing: leave -k out to run every test",
                          key=option)
    try:
        Expression.compile(expression)
    except SyntaxError as exc:
        raise ConfigError(f"{expression!r} is not a pytest -k expression: at column "
                          f"{exc.offset}: {exc.msg}", key=option) from None


def check_launchable(profile: Any, *, bus: str, clock: str, build: Path | None) -> None:
    """Refuse a process DUT whose command cannot be executed (missing, not executable, a
    directory), naming the file and ``[launch] command``, before any run starts: otherwise
    every test fails with the same setup error and no measurement."""
    from hil.dut.factory import runs_inprocess
    from hil.dut.process import command_line

    if profile.dut.kind == "physical" or runs_inprocess(profile, bus) \
            or not profile.launch.command:
        return
    program = command_line(profile, bus=bus, clock=clock, build=build)[0]
    where = {"path": str(profile.path), "key": "launch.command"}
    if os.sep not in program:
        if shutil.which(program) is None:
            raise ConfigError(f"{program!r} is not a command on PATH", **where)
        return
    target = Path(program)
    if not target.exists():
        raise ConfigError(f"{target} does not exist", **where)
    if target.is_dir() or not os.access(target, os.X_OK):
        raise ConfigError(f"{target} is not an executable file "
                          f"({'a directory' if target.is_dir() else 'no execute permission'})",
                          **where)
