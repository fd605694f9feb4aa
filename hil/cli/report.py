"""``hil report QUAL_DIR [--open]``: (re)write the qualification report of a directory.

Exit status: 0 written, 2 when ``QUAL_DIR/record.json`` is missing or not a qualification
record (the message names the file).
"""

from __future__ import annotations

import argparse
import webbrowser
from pathlib import Path


def add_subparser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    sub = subparsers.add_parser(
        "report", help="write report.html of a qualification directory",
        description="Read QUAL_DIR/record.json (written by 'hil qualify') and the runs under "
                    "it; write the self-contained QUAL_DIR/report.html.")
    sub.add_argument("qual_dir", metavar="QUAL_DIR", help="qualification directory")
    sub.add_argument("--open", action="store_true", help="open the report in a browser")
    sub.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from hil.report import write_html

    path = write_html(Path(args.qual_dir))
    size_kb = path.stat().st_size / 1024
    print(f"hil: wrote {path} ({size_kb:,.0f} kB)")
    if args.open:
        webbrowser.open(path.resolve().as_uri())
    return 0
