"""``hil report``: placeholder until its module lands (being written now)."""

from __future__ import annotations

import argparse
import sys


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    sub = subparsers.add_parser("report", help="(not built yet)")
    sub.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    print("hil: 'report' is not built yet", file=sys.stderr)
    return 2
