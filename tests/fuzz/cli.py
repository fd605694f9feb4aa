"""Run the ``hil`` command line in-process (fast) and check what a user sees on bad input."""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from pathlib import Path

from hil.cli.main import main


@dataclass
class Outcome:
    code: int
    stdout: str
    stderr: str

    def error_lines(self) -> list[str]:
        return [line for line in self.stderr.splitlines() if line.strip()]


def run_cli(*argv: str) -> Outcome:
    """``hil ARGV`` in this process, its exit status and output (exceptions propagate)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(argv))
        except SystemExit as exc:  # argparse
            code = int(exc.code or 0) if not isinstance(exc.code, str) else 2
    return Outcome(int(code), out.getvalue(), err.getvalue())


def assert_refused(outcome: Outcome, path: Path, what: str) -> None:
    """Exit 2, one line, the file named, no traceback."""
    assert outcome.code == 2, (what, outcome)
    assert "Traceback" not in outcome.stderr, (what, outcome.stderr)
    lines = outcome.error_lines()
    assert len(lines) == 1, (what, lines)
    assert path.name in lines[0], (what, lines[0])
