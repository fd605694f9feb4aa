"""Bad command-line arguments for every ``hil`` subcommand: exit 2, one line, no traceback,
before anything runs.

Each example is run as a separate ``hil`` process with a time limit (a refused option must not
start a bus server that serves for ever or a qualification that runs for a minute). In the
default run with 30 examples (~10 s); ``AGRIHIL_FUZZ_CLI_EXAMPLES`` raises that. The loaders
behind the files are fuzzed in test_fuzz_files.py.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.fuzz.cli_cases import ROOT, bad_argv


@settings(max_examples=int(os.environ.get("AGRIHIL_FUZZ_CLI_EXAMPLES", "30")))
@given(data=st.data())
def test_bad_arguments_are_refused_up_front(data: st.DataObject,
                                            tmp_path_factory: pytest.TempPathFactory) -> None:
    tmp = tmp_path_factory.mktemp("cli")
    case, argv = data.draw(bad_argv(tmp))
    try:
        done = subprocess.run([sys.executable, "-m", "hil", *argv], cwd=ROOT, text=True,
                              capture_output=True, timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{case}: {argv} was accepted and still ran after 60 s")
    assert "Traceback" not in done.stderr, (case, done.stderr[-1500:])
    assert done.returncode == 2, (case, argv, done.returncode, done.stderr[-800:])
    errors = [line for line in done.stderr.splitlines()
              if line.strip() and not line.startswith(("usage:", " ", "hil: running",
                                                         "hil: qualifying", "hil: build"))]
    assert len(errors) == 1, (case, errors)
    assert not any(Path(tmp / "out").glob("**/record.json")), (case, "a run was recorded")
