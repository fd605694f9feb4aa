"""Shared fixtures: an embedded software bus, and a leak check for threads."""

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
