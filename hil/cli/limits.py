"""``hil limits``: the measurement catalogue with its default limits and their sources.

    hil limits
    hil limits --rig sowing_depth --format json

What every qualification judges a measurement against when the DUT's profile sets no limit
for it (``hil/limits.py``), and where that default comes from (the paper, table or standard,
or the rig's own derivation), or why it is information only. No docs build needed: the same
table as docs/reference/measurements.md. ``hil profile check`` prints it for one DUT, with its
profile's tightened and loosened limits.
"""

from __future__ import annotations

import argparse
import json

from hil.effective_limits import EffectiveLimit, effective_limits
from hil.errors import ConfigError
from hil.limits import MEASUREMENTS


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    cmd = subparsers.add_parser("limits", help="print the measurement catalogue with its "
                                               "default limits and their sources")
    cmd.add_argument("--rig", help="only this rig's measurements (fertilizer, sowing_depth; "
                                   "default: every rig)")
    cmd.add_argument("--format", choices=["text", "json"], default="text",
                     help="text (aligned columns) or json (a list of objects)")
    cmd.set_defaults(func=_limits)


def rigs() -> list[str]:
    """The rigs the catalogue names (``*``: measurements of every rig)."""
    return sorted({spec.rig for spec in MEASUREMENTS.values()} - {"*"})


def catalogue(rig: str | None) -> list[tuple[str, EffectiveLimit]]:
    """(rig, limit) per measurement; the ``*`` measurements once, under ``*``."""
    if rig is not None:
        rig = rig.replace("-", "_")
        if rig not in rigs():
            raise ConfigError(f"no measurements for rig {rig!r} (the catalogue's rigs: "
                              f"{', '.join(rigs())})", key="--rig")
        return [(MEASUREMENTS[lim.name].rig, lim) for lim in effective_limits(rig, {})]
    out: list[tuple[str, EffectiveLimit]] = []
    for name in rigs():
        out += [(name, lim) for lim in effective_limits(name, {})
                if MEASUREMENTS[lim.name].rig == name]
    return out + [("*", lim) for lim in effective_limits(rigs()[0], {})
                  if MEASUREMENTS[lim.name].rig == "*"]


def _limits(args: argparse.Namespace) -> int:
    rows = catalogue(args.rig)
    if args.format == "json":
        print(json.dumps([{"rig": rig, **lim.to_dict()} for rig, lim in rows], indent=2))
        return 0
    width = max(len(lim.name) for _, lim in rows)
    for rig, lim in rows:
        limit = "information only" if lim.origin == "information" \
            else f"{lim.text} [{lim.unit}]"
        basis = lim.information if lim.origin == "information" else lim.source
        print(f"{rig:<12}  {lim.name:<{width}}  {limit}  ({basis or 'no source stated'})")
    return 0
