from __future__ import annotations

import pytest

from hil.softbus.faults import FaultError, FaultKind, FaultRule, FaultTable


def test_parse_and_match() -> None:
    rule = FaultRule.parse(["drop", "id=0x180", "mask=0x780", "count=2"])
    assert rule.matches(0x181) and rule.matches(0x1FF) and not rule.matches(0x201)
    exact = FaultRule.parse(["drop", "id=0x181"])
    assert exact.matches(0x181) and not exact.matches(0x182)
    assert FaultRule.parse(["drop"]).matches(0x7FF)


@pytest.mark.parametrize("words", [[], ["melt"], ["drop", "p=2"], ["drop", "colour=red"],
                                   ["delay"], ["drop", "id=zz"]])
def test_bad_rules_are_refused(words: list[str]) -> None:
    with pytest.raises(FaultError):
        FaultRule.parse(words)


def test_count_limits_and_probability_is_seeded() -> None:
    table = FaultTable(seed=1)
    table.add(FaultRule(FaultKind.DROP, count=3))
    assert [table.apply(0x100, b"").drop for _ in range(5)] == [True] * 3 + [False] * 2

    def pattern(seed: int) -> list[bool]:
        t = FaultTable(seed=seed)
        t.add(FaultRule(FaultKind.DROP, probability=0.5))
        return [t.apply(0x100, b"").drop for _ in range(64)]

    assert pattern(7) == pattern(7)
    assert pattern(7) != pattern(8)
    assert 10 < sum(pattern(7)) < 54


def test_corrupt_changes_payload_keeps_length() -> None:
    table = FaultTable()
    table.add(FaultRule(FaultKind.CORRUPT))
    verdict = table.apply(0x100, bytes(8))
    assert verdict.data is not None and len(verdict.data) == 8 and verdict.data != bytes(8)


def test_busoff_sends_one_error_then_silences_the_node() -> None:
    table = FaultTable()
    rule_id = table.add(FaultRule(FaultKind.BUSOFF, can_id=0x181, mask=0x7FF))
    first = table.apply(0x181, b"\x01")
    assert first.drop and first.error_frame
    later = table.apply(0x181, b"\x01")
    assert later.drop and not later.error_frame
    assert not table.apply(0x182, b"\x01").drop
    table.clear(rule_id)
    assert not table.apply(0x181, b"\x01").drop
    with pytest.raises(FaultError):
        table.clear(rule_id)
