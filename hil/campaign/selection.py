"""Does a campaign's ``--suite`` and ``-k`` select any test? Asked before any worker starts.

A campaign whose selection is empty would start a cluster, run N empty samples and end with "no
sample completed"; pytest's own collection (``--collect-only``, in a subprocess: the driver must
not import the suites) answers in a few seconds instead.
"""

from __future__ import annotations

import re
import subprocess
import tempfile
from pathlib import Path

from hil.campaign.sample import SampleTask, pytest_argv
from hil.errors import ConfigError, HilError

#: pytest's exit statuses (pytest.ExitCode) that this check tells apart
_NO_TESTS, _USAGE = 5, 4


def check_selection(task: SampleTask, *, timeout_s: float = 600.0) -> int:
    """The number of tests ``task`` selects; refuse a selection of none.

    Parameters
    ----------
    task : SampleTask
        Sample 0 of the campaign (its profile, bus, suites and ``-k``).
    timeout_s : float
        How long the collection may take.

    Returns
    -------
    int
        The tests selected (at least 1).

    Raises
    ------
    ConfigError
        Nothing is selected (naming ``-k``, or ``--suite`` without one) or pytest refuses the
        options.
    """
    with tempfile.TemporaryDirectory(prefix="agrihil-collect-") as scratch:
        argv = [*pytest_argv(task, Path(scratch)), "--collect-only", "-q"]
        try:
            done = subprocess.run(argv, capture_output=True, text=True, timeout=timeout_s,
                                  stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired as exc:
            raise HilError(f"collecting the suites took longer than {timeout_s:g} s") from exc
    selected = _count(done.stdout)
    if done.returncode == _NO_TESTS or (done.returncode == 0 and not selected):
        if task.keyword:
            raise ConfigError(f"{task.keyword!r} selects no test of suites {task.suites}",
                              key="-k")
        raise ConfigError(f"suites {task.suites} hold no test for this rig", key="--suite")
    if done.returncode != 0:
        tail = (done.stderr.strip() or done.stdout.strip()).splitlines()[-1:] or ["no output"]
        raise ConfigError(f"pytest refuses the selection (exit {done.returncode}): {tail[0]}",
                          key="-k" if task.keyword else "--suite")
    return selected


def _count(output: str) -> int:
    """Tests listed by ``--collect-only -qq`` (``file.py: N`` lines) or ``-q`` (node ids)."""
    total = 0
    for line in output.splitlines():
        per_file = re.fullmatch(r"\S+\.py: (\d+)", line.strip())
        if per_file:
            total += int(per_file.group(1))
        elif "::" in line and " " not in line.strip():
            total += 1
    return total
