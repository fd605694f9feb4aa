"""``hil run``: run one scenario of a rig against a DUT."""

from __future__ import annotations

import argparse
import sys


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    run = subparsers.add_parser("run", help="run one scenario of a rig against a DUT")
    run.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    print("hil: 'run' is not built yet (see issue: fertilizer rig)", file=sys.stderr)
    return 2
