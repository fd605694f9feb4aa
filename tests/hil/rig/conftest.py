"""A test module that sets ``RUN_EACH_TEST_IN_A_FORK = True`` has each test run in a forked copy
of the worker: a process with no other thread, whatever threads earlier tests of the session
left behind (a software bus server, a Dask client, python-can's notifiers). The prefix
checkpoints (:mod:`hil.rig.checkpoint`) hold a run only in such a process, as a campaign's
forked sample is; in a long session's worker they would silently never hold."""

from __future__ import annotations

import os
import traceback

import pytest


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> bool | None:
    if not getattr(pyfuncitem.module, "RUN_EACH_TEST_IN_A_FORK", False):
        return None
    args = {name: pyfuncitem.funcargs[name] for name in pyfuncitem._fixtureinfo.argnames}
    read_fd, write_fd = os.pipe()
    pid = os.fork()
    if pid == 0:                                   # the copy: run the test, report, leave
        os.close(read_fd)
        failure = ""
        try:
            pyfuncitem.obj(**args)
        except BaseException:
            failure = traceback.format_exc()
        finally:
            from hil.rig import checkpoint

            checkpoint.release_all()
        with os.fdopen(write_fd, "w") as pipe:
            pipe.write(failure)
        os._exit(1 if failure else 0)
    os.close(write_fd)
    with os.fdopen(read_fd) as pipe:
        failure = pipe.read()
    _, status = os.waitpid(pid, 0)
    if failure or status != 0:
        pytest.fail(f"in the test's forked process:\n{failure or f'wait status {status}'}",
                    pytrace=False)
    return True
