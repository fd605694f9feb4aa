"""Named phase boundaries of the long commands, where tests inject a signal.

``hil qualify``, ``hil campaign`` and ``hil run`` call :func:`phase` at each boundary (setup
done, build done, suites started, each test or sample, record written, rerun, promote; for
``hil run``: ``run:built`` before ``--out`` is touched, ``run:staged``, ``run:written`` once the
run's files are staged, ``run:promote`` while they move in). With the environment
variable ``HIL_TEST_SIGNAL_AT`` set to ``NAME`` (or ``NAME@N``: the N-th time that phase is
reached, counting from 1), the process sends itself SIGINT there, so a test proves that a
signal at that exact moment is neither lost nor turned into a pass, without relying on timing.
A trailing ``/group`` sends it to the whole process group instead, as Ctrl-C on a terminal
does (Dask workers included).
Unset (always, outside tests), :func:`phase` does nothing.
"""

from __future__ import annotations

import os
import signal

__all__ = ["ENV", "phase"]

#: the environment variable naming the phase to interrupt
ENV = "HIL_TEST_SIGNAL_AT"

_reached: dict[str, int] = {}


def phase(name: str) -> None:
    """Mark the boundary ``name``; sends SIGINT to this process when ``HIL_TEST_SIGNAL_AT``
    names it (see the module docstring)."""
    wanted = os.environ.get(ENV)
    if not wanted:
        return
    wanted, group, _ = wanted.partition("/group")
    target, _, nth = wanted.partition("@")
    if target != name:
        return
    _reached[name] = _reached.get(name, 0) + 1
    if _reached[name] == (int(nth) if nth.isdigit() else 1):
        if group:
            os.killpg(os.getpgid(0), signal.SIGINT)
        else:
            os.kill(os.getpid(), signal.SIGINT)

