"""Bad command-line arguments for every ``hil`` subcommand: exit 2, one line, no traceback,
before anything runs.

Each example is run as a separate ``hil`` process with a time limit (a refused option must not
start a bus server that serves for ever or a qualification that runs for a minute), forked
from a server that imported ``hil`` once (tests/helpers/hil_forkserver.py: ~14 s of CPU for 30
examples as new interpreters, ~2 s forked). In the default run with 30 examples;
``AGRIHIL_FUZZ_CLI_EXAMPLES`` raises that. The loaders behind the files are fuzzed in
test_fuzz_files.py.
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
from tests.helpers.hil_forkserver import HilForkServer, HilTimeout


@settings(max_examples=int(os.environ.get("AGRIHIL_FUZZ_CLI_EXAMPLES", "30")))
@given(data=st.data())
def test_bad_arguments_are_refused_up_front(data: st.DataObject,
                                            tmp_path_factory: pytest.TempPathFactory,
                                            hil_forked: HilForkServer) -> None:
    tmp = tmp_path_factory.mktemp("cli")
    case, argv = data.draw(bad_argv(tmp))
    try:
        done = hil_forked.run(argv, ROOT, timeout_s=60)
    except HilTimeout:
        pytest.fail(f"{case}: {argv} was accepted and still ran after 60 s")
    assert "Traceback" not in done.stderr, (case, done.stderr[-1500:])
    assert done.returncode == 2, (case, argv, done.returncode, done.stderr[-800:])
    errors = [line for line in done.stderr.splitlines()
              if line.strip() and not line.startswith(("usage:", " ", "hil: running",
                                                         "hil: qualifying", "hil: build"))]
    assert len(errors) == 1, (case, errors)
    assert not any(Path(tmp / "out").glob("**/record.json")), (case, "a run was recorded")


def test_the_fork_server_reports_what_a_hil_process_does(tmp_path: Path,
                                                        hil_forked: HilForkServer) -> None:
    """The fuzz test's checks are only as good as its runner: the fork server sees the exit
    status, the one-line error as ``python -m hil`` prints it, a traceback, and a command
    that does not stop (killed at the time limit, the server still serving)."""
    missing = str(tmp_path / "none.toml")

    def direct(*argv: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "hil", *argv], cwd=ROOT,
                              capture_output=True, text=True, timeout=60)

    helped = hil_forked.run(["--help"], ROOT, timeout_s=60)
    assert helped.returncode == 0 and helped.stdout.startswith("usage: hil")
    refused = hil_forked.run(["profile", "check", missing], ROOT, timeout_s=60)
    checked = direct("profile", "check", missing)
    assert (refused.returncode, refused.stderr) == (checked.returncode, checked.stderr) == (
        2, f"hil: error: {missing}: DUT profile not found\n")
    crashed = hil_forked.run(["--debug", "report", missing], ROOT, timeout_s=60)
    reported = direct("--debug", "report", missing)
    assert crashed.returncode == reported.returncode == 1
    assert "Traceback (most recent call last)" in crashed.stderr
    assert crashed.stderr.splitlines()[-1] == reported.stderr.splitlines()[-1]
    with pytest.raises(HilTimeout):
        hil_forked.run(["bus", "serve", "--port", "0"], tmp_path, timeout_s=1.0)
    assert hil_forked.run(["--help"], ROOT, timeout_s=60).returncode == 0
