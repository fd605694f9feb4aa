"""Faults the software bus can inject on command.

A :class:`FaultRule` matches frames by identifier (with a mask) and, with a probability, does
one thing to each match:

``drop``
    the frame vanishes (a node or gateway losing it);
``delay``
    the frame is delivered ``delay_s`` later than the wire would deliver it;
``corrupt``
    the frame arrives with payload bits flipped (a faulty node sending garbage with a valid CRC);
``error``
    the frame is destroyed on the wire: receivers see an error frame instead of it;
``busoff``
    the sending node goes bus-off: receivers see an error frame (of the SocketCAN classes
    controller problem and bus off, ``CAN_ERR_CRTL | CAN_ERR_BUSOFF``), then no frame matching
    the rule passes until the rule is cleared.

``count`` limits how many matches a rule acts on (0 = unlimited). Randomness comes from one
seeded generator per server, so a run with the same seed and traffic injects the same faults.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from enum import StrEnum

from hil.errors import HilError

#: The longest delay a rule may add: a delayed frame waits in a timer, and a longer delay
#: only means more of them held at once.
MAX_DELAY_S = 60.0
#: The most rules at a time: every frame on the bus is checked against each.
MAX_RULES = 64


class FaultError(HilError, ValueError):
    """A fault command cannot be understood."""


class FaultKind(StrEnum):
    DROP = "drop"
    DELAY = "delay"
    CORRUPT = "corrupt"
    ERROR = "error"
    BUSOFF = "busoff"


@dataclass(frozen=True)
class FaultRule:
    """What to do to which frames. ``can_id``/``mask`` match like a SocketCAN filter."""

    kind: FaultKind
    can_id: int = 0
    mask: int = 0  # 0 matches every frame
    probability: float = 1.0
    count: int = 0
    delay_s: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.probability <= 1.0:
            raise FaultError(f"probability must be within 0..1, got {self.probability}")
        if self.count < 0:
            raise FaultError(f"count must be >= 0, got {self.count}")
        if self.kind is FaultKind.DELAY and self.delay_s <= 0:
            raise FaultError("a delay fault needs delay_s > 0")
        if not 0.0 <= self.delay_s <= MAX_DELAY_S:
            raise FaultError(f"delay_s must be within 0..{MAX_DELAY_S:g} s, got {self.delay_s}")

    def matches(self, can_id: int) -> bool:
        return (can_id & self.mask) == (self.can_id & self.mask)

    @classmethod
    def parse(cls, words: list[str]) -> FaultRule:
        """Parse ``KIND key=value …`` as sent in ``< hil fault add … >``.

        >>> rule = FaultRule.parse(["drop", "id=0x181", "mask=0x7ff", "p=0.5"])
        >>> rule.kind, hex(rule.can_id), hex(rule.mask), rule.probability
        (<FaultKind.DROP: 'drop'>, '0x181', '0x7ff', 0.5)
        """
        if not words:
            raise FaultError("fault needs a kind: " + ", ".join(k.value for k in FaultKind))
        try:
            kind = FaultKind(words[0])
        except ValueError as exc:
            raise FaultError(f"unknown fault kind {words[0]!r}; known: "
                             + ", ".join(k.value for k in FaultKind)) from exc
        values: dict[str, float | int] = {}
        names = {"id": "can_id", "mask": "mask", "p": "probability", "count": "count",
                 "delay": "delay_s"}
        for word in words[1:]:
            key, sep, text = word.partition("=")
            if not sep or key not in names:
                raise FaultError(f"bad fault option {word!r}; known: "
                                 + ", ".join(f"{k}=…" for k in names))
            try:
                values[names[key]] = (float(text) if key in ("p", "delay")
                                      else int(text, 0))
            except ValueError as exc:
                raise FaultError(f"bad value in {word!r}") from exc
        if "can_id" in values and "mask" not in values:
            values["mask"] = 0x1FFFFFFF
        return cls(kind=kind, **values)  # type: ignore[arg-type]

    def to_words(self) -> list[str]:
        return [self.kind.value, f"id=0x{self.can_id:X}", f"mask=0x{self.mask:X}",
                f"p={self.probability}", f"count={self.count}", f"delay={self.delay_s}"]


@dataclass
class _Active:
    rule: FaultRule
    applied: int = 0
    tripped: bool = False  # busoff: the node has gone off the bus


@dataclass
class Verdict:
    """What the fault table decided for one frame."""

    drop: bool = False
    error_frame: bool = False
    bus_off: bool = False  # the error frame says its sender went bus off
    delay_s: float = 0.0
    data: bytes | None = None  # replacement payload when corrupted


@dataclass
class FaultTable:
    """The server's active rules, applied in the order they were added."""

    seed: int = 0
    _rules: dict[int, _Active] = field(default_factory=dict)
    _next_id: int = 1
    injected: dict[str, int] = field(default_factory=lambda: {k.value: 0 for k in FaultKind})

    def __post_init__(self) -> None:
        self._rng = random.Random(self.seed)

    def add(self, rule: FaultRule) -> int:
        if len(self._rules) >= MAX_RULES:
            raise FaultError(f"at most {MAX_RULES} fault rules at a time (every frame is "
                             "checked against each); clear some first")
        rule_id = self._next_id
        self._next_id += 1
        self._rules[rule_id] = _Active(rule)
        return rule_id

    def clear(self, rule_id: int | None = None) -> None:
        if rule_id is None:
            self._rules.clear()
        elif self._rules.pop(rule_id, None) is None:
            raise FaultError(f"no fault rule {rule_id}")

    def rules(self) -> dict[int, FaultRule]:
        return {rid: active.rule for rid, active in self._rules.items()}

    def __bool__(self) -> bool:
        return bool(self._rules)

    def apply(self, can_id: int, data: bytes) -> Verdict:
        verdict = Verdict()
        for active in self._rules.values():
            rule = active.rule
            if not rule.matches(can_id):
                continue
            if rule.kind is FaultKind.BUSOFF and active.tripped:
                verdict.drop = True
                self.injected[rule.kind.value] += 1
                continue
            if rule.count and active.applied >= rule.count:
                continue
            if rule.probability < 1.0 and self._rng.random() >= rule.probability:
                continue
            active.applied += 1
            self.injected[rule.kind.value] += 1
            if rule.kind is FaultKind.DROP:
                verdict.drop = True
            elif rule.kind is FaultKind.DELAY:
                verdict.delay_s += rule.delay_s
            elif rule.kind is FaultKind.CORRUPT:
                payload = bytearray(verdict.data if verdict.data is not None else data)
                if payload:
                    bit = self._rng.randrange(len(payload) * 8)
                    payload[bit // 8] ^= 1 << (bit % 8)
                    payload[self._rng.randrange(len(payload))] ^= self._rng.randrange(1, 256)
                verdict.data = bytes(payload)
            elif rule.kind in (FaultKind.ERROR, FaultKind.BUSOFF):
                verdict.drop = True
                verdict.error_frame = True
                active.tripped = rule.kind is FaultKind.BUSOFF
                verdict.bus_off = verdict.bus_off or active.tripped
        return verdict
