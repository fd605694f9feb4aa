"""Shared fixtures: an embedded software bus, a leak check for threads; the longest tests first.

The test command runs on both cores (``scripts/test.sh``: pytest-xdist, ``-n 2``). xdist hands
the tests out in collection order, so a long test collected last would run alone at the end
while the other worker idles: the longest ones (the user-mode Linux guest, over a minute, above
all) are moved to the front, where they run beside the host tests. Their relative order, and
everyone else's, is kept.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from hil.softbus import SoftwareBus


@pytest.fixture
def softbus() -> Iterator[SoftwareBus]:
    with SoftwareBus(port=0) as bus:
        yield bus


@pytest.fixture(autouse=True)
def no_leaked_softbus_threads() -> Iterator[None]:
    """A test that leaves a software bus thread running fails (style: fixtures police leaks)."""
    before = {t.ident for t in threading.enumerate()}
    yield
    leaked = [t.name for t in threading.enumerate()
              if t.ident not in before and t.name == "hil-softbus" and t.is_alive()]
    assert not leaked, f"test leaked software bus threads: {leaked}"


#: test files (or node ids) that take 10 s or more, longest first, measured with
#: ``--durations`` on the project's 2-vCPU VMs (the guest 65-184 s, the physical ECU ~27 s,
#: the depth must-fail profiles ~20 s each)
LONGEST_FIRST = (
    "tests/kernel/test_guest.py",
    "tests/kernel/test_physical_ecu.py",
    "tests/test_suites_depth_discrimination.py",
    "tests/test_discrimination.py",
    "tests/hil/campaign/test_campaign_e2e.py",
    "tests/test_docs_examples.py",
    "tests/fuzz/test_fuzz_cli_args.py",
    "tests/hil/campaign/test_fork_isolation.py",
)


def _rank(nodeid: str) -> int:
    for rank, prefix in enumerate(LONGEST_FIRST):
        if nodeid.startswith(prefix):
            return rank
    return len(LONGEST_FIRST)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The longest tests first (a stable sort: every other order is kept)."""
    items.sort(key=lambda item: _rank(item.nodeid))
