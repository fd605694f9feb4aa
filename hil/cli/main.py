"""Entry point of the ``hil`` command.

Exit status: 0 pass, 1 fail (a run or a check failed, the DUT stopped), 2 usage or setup
error (one line; an internal error says so and asks for ``--debug``), 130 interrupted.
``--debug`` shows tracebacks instead of one-line errors.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import signal
import sys
from collections.abc import Sequence
from types import FrameType
from typing import Any, NoReturn

from hil import __version__
from hil.errors import HilError

EXIT_PASS = 0
EXIT_FAIL = 1
EXIT_SETUP = 2

#: Subcommand modules, imported in order; each provides ``add_subparser(subparsers)``.
SUBCOMMANDS = ("hil.cli.bus", "hil.cli.run", "hil.cli.profile", "hil.cli.qualify",
               "hil.cli.gate", "hil.cli.report", "hil.cli.campaign", "hil.cli.isobus",
               "hil.cli.rig", "hil.cli.limits", "hil.cli.fmu")


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so every ``with`` block flushes what it recorded."""


class _Interrupts:
    """SIGINT and SIGTERM: the first one raises (``KeyboardInterrupt`` / :class:`Terminated`)
    so every ``with`` block writes what it recorded; every later one is counted and ignored,
    so a second Ctrl-C cannot cut the writing of the record short (SIGKILL still ends it)."""

    def __init__(self) -> None:
        self.count = 0

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        self.count += 1
        if self.count == 1:
            if signum == signal.SIGTERM:
                raise Terminated(f"signal {signum}")
            raise KeyboardInterrupt
        print(f"hil: {signal.Signals(signum).name} again: still writing what was recorded "
              f"(SIGKILL abandons it)", file=sys.stderr, flush=True)


#: how many SIGINT/SIGTERM the running command has received (0: none)
INTERRUPTS = _Interrupts()
_on_sigterm = INTERRUPTS   # the name earlier code installs as the SIGTERM handler


class _Parser(argparse.ArgumentParser):
    """argparse, with a usage error on one line (and where to read the usage)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_SETUP, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="hil", description="agrihil: hardware-in-the-loop rigs for agricultural CAN "
                                "controllers")
    parser.add_argument("--version", action="version", version=f"agrihil {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output (repeat for debug logs)")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers.required = True
    for module_name in SUBCOMMANDS:
        importlib.import_module(module_name).add_subparser(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    INTERRUPTS.count = 0
    previous = {sig: signal.signal(sig, INTERRUPTS) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse exits 2 on usage errors, 0 on --help
        _restore(previous)
        return int(exc.code or 0)
    except KeyboardInterrupt:   # before the command began: nothing was touched
        _restore(previous)
        print("hil: interrupted before the command began; nothing was written",
              file=sys.stderr)
        return 130
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        code = int(args.func(args))
        if INTERRUPTS.count:
            # the signal's KeyboardInterrupt was swallowed on its way (raised inside a
            # finalizer or a library's catch-all) and the command ran on: the signal is
            # still the user's, never lost, and the exit status says so
            print("hil: interrupted (the command finished its work first; what it recorded "
                  "has been written)", file=sys.stderr)
            return 130
        return code
    except KeyboardInterrupt:
        print("hil: interrupted; what was recorded so far has been written", file=sys.stderr)
        return 130
    except HilError as exc:
        if args.debug:
            raise
        print(f"hil: error: {exc}", file=sys.stderr)
        return EXIT_SETUP
    except (OSError, ValueError, OverflowError) as exc:
        # what user input provokes from the libraries (a path that cannot be written, a
        # number out of range, a log format python-can does not know): one line, exit 2
        if args.debug:
            raise
        print(f"hil: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_SETUP
    except Exception as exc:
        # a bug of agrihil's, not the user's: said as such, never swallowed silently
        if args.debug:
            raise
        print(f"hil: internal error: {type(exc).__name__}: {_one_line(exc, kind=False)} "
              f"(a bug: rerun with --debug for the traceback and report it)", file=sys.stderr)
        return EXIT_SETUP
    finally:
        _restore(previous)


def _one_line(exc: BaseException, *, kind: bool = True) -> str:
    """An exception as one line: an OSError's file and reason, else its message."""
    if isinstance(exc, OSError) and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    else:
        text = str(exc) or type(exc).__name__
        if kind and not isinstance(exc, HilError):
            text = f"{text} ({type(exc).__name__})"
    return " ".join(text.split())


def _restore(previous: dict[signal.Signals, Any]) -> None:
    """Put the caller's handlers back; after an interruption, ignore SIGINT/SIGTERM instead:
    a second Ctrl-C between the command's end and the process's must not turn the exit
    status 130 into death by signal."""
    for sig, handler in previous.items():
        signal.signal(sig, handler if INTERRUPTS.count == 0 else signal.SIG_IGN)
