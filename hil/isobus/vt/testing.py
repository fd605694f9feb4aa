"""Operating a VT from pytest: press by id or label, wait for a mask, read a field.

:class:`VtOperatorDriver` wraps a VT server and whatever advances the run (a
:class:`~hil.isobus.vt.bench.VtBench`, a rig run in lockstep: anything with ``run_for`` and
``now``); each call acts now and runs the bench until the VT has said it. The
``vt_operator`` fixture builds one from a ``vt_bench`` fixture the test module provides::

    from hil.isobus.vt.testing import vt_operator   # noqa: F401 (the fixture)

    @pytest.fixture
    def vt_bench() -> VtBench:
        bench = VtBench([pool.to_bytes()])
        bench.run_until(3.0)
        return bench

    def test_master(vt_operator, vt_bench):
        vt_operator.press("Master")
        vt_operator.wait_for_mask(1001, timeout_s=2.0)
        assert vt_operator.value(5001) == 25.0
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Protocol

import pytest

from hil.isobus.vt.layouts import ObjectType
from hil.isobus.vt.operator import ENTERABLE, PRESSABLE, Operator, Target, find, shown_value
from hil.isobus.vt.server import VirtualTerminalServer
from hil.isobus.vt.workingset import WorkingSet

T = ObjectType
#: how often wait_for_mask looks
POLL_S = 0.05


class Advancing(Protocol):
    """What runs the VT: a bench or a rig run."""

    vt: VirtualTerminalServer

    @property
    def now(self) -> float:
        """Run time reached."""

    def run_for(self, seconds: float) -> None:
        """Advance the run."""


class VtOperatorDriver:
    """The operator in a test: acts now, then lets the run go on until it is done."""

    def __init__(self, bench: Advancing, address: int | None = None) -> None:
        self.bench = bench
        self.operator = Operator(bench.vt, address)

    @property
    def ws(self) -> WorkingSet:
        """The working set operated on."""
        return self.bench.vt._working_set(self.operator.address)

    def _done(self, before: int, seconds: float) -> None:
        self.bench.run_for(seconds)
        if len(self.operator.missed) > before:
            raise AssertionError(self.operator.missed[-1][1])

    def press(self, target: Target, hold_s: float = 0.2) -> None:
        """Press a soft key or button (id or label) and release it after ``hold_s``."""
        find(self.ws, target, PRESSABLE)
        before = len(self.operator.missed)
        self.operator.press(target, self.bench.now, hold_s)
        self._done(before, hold_s + 0.05)

    def enter(self, target: Target, value: float) -> None:
        """Enter ``value`` (as shown) into an input number, list or boolean."""
        find(self.ws, target, ENTERABLE)
        before = len(self.operator.missed)
        self.operator.enter(target, value, self.bench.now)
        self._done(before, 0.05)

    def type(self, target: Target, text: str) -> None:
        """Type ``text`` into an input string."""
        before = len(self.operator.missed)
        self.operator.type(target, text, self.bench.now)
        self._done(before, 0.05)

    def acknowledge(self, key: Target | None = None) -> None:
        """Acknowledge the alarm shown."""
        before = len(self.operator.missed)
        self.operator.acknowledge(self.bench.now, key)
        self._done(before, 0.3)

    def wait_for_mask(self, mask: Target, timeout_s: float = 5.0) -> float:
        """Run until the working set shows ``mask`` (id, or a data/alarm mask's id as text);
        the run time it appeared.

        Raises
        ------
        AssertionError
            Not within ``timeout_s``, naming the mask shown instead.
        """
        wanted = int(mask)
        end = self.bench.now + timeout_s
        while True:
            vt = self.bench.vt
            ws = vt.active_working_set if self.operator.address is None else \
                vt.sessions.get(self.operator.address)
            if ws is not None and ws.active_mask == wanted:
                return self.bench.now
            if self.bench.now >= end - 1e-9:
                shown = ws.active_mask if ws is not None else None
                raise AssertionError(f"mask {wanted} not shown within {timeout_s:g} s "
                                     f"(shown: {shown})")
            self.bench.run_for(POLL_S)

    def value(self, target: Target) -> float | str:
        """What a field shows now: a number object's value in its units (offset, scale,
        decimals applied), a string's text, an input list's index."""
        ws = self.ws
        obj = find(ws, target, tuple(ObjectType))
        if obj.type in (T.OUTPUT_STRING, T.INPUT_STRING, T.STRING_VARIABLE):
            return ws.text(obj)
        raw = ws.number(obj)
        if obj.type in (T.OUTPUT_NUMBER, T.INPUT_NUMBER):
            return shown_value(obj, raw)
        return float(raw)


@pytest.fixture
def vt_operator(vt_bench: Any) -> Iterator[VtOperatorDriver]:
    """The operator of the VT in the test's ``vt_bench`` fixture."""
    yield VtOperatorDriver(vt_bench)
