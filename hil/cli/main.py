"""Entry point of the ``hil`` command.

Exit status: 0 pass, 1 fail (a run or a check failed), 2 usage or setup error.
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

from hil import __version__
from hil.errors import HilError

EXIT_PASS = 0
EXIT_FAIL = 1
EXIT_SETUP = 2

#: Subcommand modules, imported in order; each provides ``add_subparser(subparsers)``.
SUBCOMMANDS = ("hil.cli.bus", "hil.cli.run", "hil.cli.profile", "hil.cli.qualify",
               "hil.cli.gate", "hil.cli.report", "hil.cli.campaign")


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so every ``with`` block flushes what it recorded."""


def _on_sigterm(signum: int, frame: FrameType | None) -> None:
    raise Terminated(f"signal {signum}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
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
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse exits 2 on usage errors, 0 on --help
        return int(exc.code or 0)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("hil: interrupted; what was recorded so far has been written", file=sys.stderr)
        return 130
    except HilError as exc:
        if args.debug:
            raise
        print(f"hil: error: {exc}", file=sys.stderr)
        return EXIT_SETUP
    finally:
        signal.signal(signal.SIGTERM, previous)
