"""Shared fixtures: an embedded software bus, a leak check for threads; the longest tests first.

The test command runs on both cores (``scripts/test.sh``: pytest-xdist, ``-n 2 --dist
loadgroup``). xdist hands the tests out in collection order, one or two at a time to whichever
worker is free, so a long test collected late would run alone at the end while the other worker
idles: the longest ones (the user-mode Linux guest above all) are moved to the front, longest
first, where they run beside each other and the short tests fill the gaps. Their relative order,
and everyone else's, is kept.

An expensive session fixture is built once for both workers (tests/helpers/session_shared.py):
the first test to need it is listed here, early, the others keep their place, later, and so
find it built rather than wait for it.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from hil.softbus import SoftwareBus
from tests.helpers.hil_forkserver import HilForkServer


@pytest.fixture
def softbus() -> Iterator[SoftwareBus]:
    with SoftwareBus(port=0) as bus:
        yield bus


@pytest.fixture(scope="session")
def hil_forked(tmp_path_factory: pytest.TempPathFactory) -> Iterator[HilForkServer]:
    """``python -m hil`` run in the repository, as processes forked from one server per worker
    that imported ``hil`` once (tests/helpers/hil_forkserver.py): a ``hil qualify`` costs ~1.7 s
    of CPU instead of ~3.4 s in a new interpreter (measured, 3 runs of one step test)."""
    with HilForkServer(tmp_path_factory.mktemp("hil-forked")) as server:
        yield server


@pytest.fixture(autouse=True)
def no_leaked_softbus_threads() -> Iterator[None]:
    """A test that leaves a software bus thread running fails (style: fixtures police leaks)."""
    before = {t.ident for t in threading.enumerate()}
    yield
    leaked = [t.name for t in threading.enumerate()
              if t.ident not in before and t.name == "hil-softbus" and t.is_alive()]
    assert not leaked, f"test leaked software bus threads: {leaked}"


DOCS = "tests/test_docs_examples.py::test_doc_examples"

#: test files or node ids (prefixes) that take 8 s or more, longest first, as measured with
#: ``--durations`` on the project's 2-vCPU VMs on a quiet machine (the guest 37-57 s). A docs
#: page is run as units, one test each (tests/test_docs_examples.py: ``[page]``, ``[page:LINE]``):
#: a page named here puts all its units here, its long one (the comment) and its short ones, so
#: that an edit of the page, which moves LINE, does not move them back. Of the pages whose units
#: make the same ``hil qualify`` (run once per session, the others copy it) only the first to run
#: is listed, so the others find it done rather than wait for it.
LONGEST_FIRST = (
    "tests/kernel/test_guest.py",
    # ~30 s: a depth firmware qualify; ~12 s: a must-fail one, shared with qualification.md
    f"{DOCS}[docs/getting-started/tour.md",
    # ~20 s: the fertilizer firmware's qualify that qualification.md and record-format.md
    # copy (listed so that they find it done rather than wait for it)
    f"{DOCS}[docs/guide/gate-and-ci.md",
    f"{DOCS}[docs/guide/physical-ecu.md",                   # ~26 s in real time
    "tests/test_suites_depth_discrimination.py",            # 2 x ~20 s, 4 x ~6 s
    "tests/test_discrimination.py",                         # ~14 s, 4 x 4-8 s
    "tests/test_discrimination_isobus.py",                  # ~12 s, 2 x ~4 s
    "tests/hil/campaign/test_fork_isolation.py",            # ~12 s, 2 x ~5 s
    f"{DOCS}[docs/guide/writing-a-fertilizer-controller.md",  # ~11 s
    # builds the browser tests' two qualifications (~10 s) for the other 10
    "tests/browser/test_report_in_chromium.py::test_page_loads_without_console_errors[pass]",
    "tests/hil/campaign/test_campaign_e2e.py",              # ~8 s
    "tests/test_docs_build.py",                             # ~8 s
    "tests/hil/reliability/test_signal_at_every_phase.py",
    "tests/hil/reliability/test_interrupted_qualification.py",
    "tests/hil/reliability/test_dead_dut_qualification.py",
    f"{DOCS}[docs/getting-started/reading-a-report.md",     # ~6 s
    "tests/hil/conformance/test_discrimination_bus.py",
    "tests/hil/test_pytest_plugin.py",
    "tests/test_busload_suite.py",
    DOCS,                                                   # the other docs units, 1-8 s
    "tests/kernel/test_physical_ecu.py",                    # ~5 s, ~3.5 s
    "tests/plant_emulators/test_sowing_depth_rig.py",
    "tests/firmware/test_dut_bus_close.py",
)


def _rank(nodeid: str) -> int:
    for rank, prefix in enumerate(LONGEST_FIRST):
        if nodeid.startswith(prefix):
            return rank
    return len(LONGEST_FIRST)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The longest tests first (a stable sort: every other order is kept)."""
    items.sort(key=lambda item: _rank(item.nodeid))
