"""Address claim of one internal control function (ISO 11783-5, clause 4.4).

A control function claims its preferred address with the address-claimed message (PGN 0xEE00,
its NAME as data, sent to everyone) and sends nothing else for 250 ms. A claim for the same
address from another NAME is a contention: the lower NAME wins. The winner repeats its claim;
the loser, if its NAME is self-configurable, claims another free address from 128-247
(ISO 11783-5's range for self-configurable addresses), and otherwise sends "cannot claim": the
address-claimed message from the null address 0xFE. A request for the address-claimed PGN
(PGN 0xEA00 with data ``00 EE 00``) sent to everyone or to the function's address makes it
repeat its claim (or its cannot-claim).

Not emulated: the pseudo-random delay of 0-153 ms that ISO 11783-5 puts before a cannot-claim
answer to a request (0 here, so that runs are deterministic), and commanded addresses
(PGN 0xFED8).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from hil.isobus.name import IsobusName
from hil.isobus.port import GLOBAL_ADDRESS, NULL_ADDRESS
from hil.isobus.tp_messages import PGN_ADDRESS_CLAIMED

CLAIM_WAIT_S = 0.25
"""Time after a claim before the control function may send anything else."""
SELF_CONFIGURABLE_RANGE = range(128, 248)
"""Addresses a self-configurable control function may take when it loses its own."""
CLAIM_PRIORITY = 6
EVENTS_KEPT = 256
"""How many of its last claim events a control function keeps (a peer that claims its address
again and again must not grow them without bound)."""

#: put one frame on the bus now: (priority, pgn, source, destination, data)
SendFrame = Callable[[int, int, int, int, bytes], None]


@dataclass(frozen=True)
class ClaimEvent:
    """A step of a control function's claim, for logs and tests.

    Attributes
    ----------
    time_s : float
        Run time.
    kind : str
        ``claim``, ``claimed`` (the 250 ms passed), ``defended``, ``lost``, ``moved``,
        ``cannot-claim``, ``answered-request``.
    address : int
        The address concerned.
    detail : str
        The contender's NAME, for contentions.
    """

    time_s: float
    kind: str
    address: int
    detail: str = ""


class AddressClaimer:
    """The claim state of one internal control function.

    Parameters
    ----------
    name : IsobusName
        The function's NAME.
    preferred_address : int
        The address it claims first (0 .. 253).
    send_frame : SendFrame
        Puts a frame on the bus now.
    is_free : callable
        ``is_free(address)``: whether no one else holds ``address`` (for a self-configurable
        function looking for another one).
    """

    def __init__(self, name: IsobusName, preferred_address: int, send_frame: SendFrame,
                 is_free: Callable[[int], bool]) -> None:
        if not 0 <= preferred_address <= 253:
            raise ValueError(f"{name.describe()}: preferred address {preferred_address} is not "
                             f"0 .. 253")
        self.name = name
        self.preferred_address = preferred_address
        self._send = send_frame
        self._is_free = is_free
        #: the address being claimed or held; NULL_ADDRESS after cannot-claim; None: not started
        self.current: int | None = None
        self.settle_at = float("inf")
        self.settled = False
        self.events: deque[ClaimEvent] = deque(maxlen=EVENTS_KEPT)

    @property
    def address(self) -> int | None:
        """The claimed address once 250 ms passed without a lost contention, else ``None``."""
        if self.settled and self.current not in (None, NULL_ADDRESS):
            return self.current
        return None

    @property
    def cannot_claim(self) -> bool:
        """Whether the function gave up (sent cannot-claim)."""
        return self.current == NULL_ADDRESS

    def start(self, now: float) -> None:
        """Claim the preferred address."""
        self._claim(self.preferred_address, now)

    def next_due(self) -> float:
        """When the claim settles (``inf`` when nothing is pending)."""
        return self.settle_at

    def poll(self, now: float) -> None:
        """Settle the claim once 250 ms passed."""
        if not self.settled and now >= self.settle_at and self.current not in (None,
                                                                               NULL_ADDRESS):
            self.settled = True
            self.settle_at = float("inf")
            self.events.append(ClaimEvent(now, "claimed", self.current))

    def on_claim(self, source: int, name_value: int, now: float) -> None:
        """Another control function claimed ``source`` with NAME ``name_value``."""
        if self.current in (None, NULL_ADDRESS) or source != self.current:
            return
        ours = self.name.value
        if name_value == ours:
            return   # our own claim (looped back) or a duplicate NAME: nothing to contend
        if name_value > ours:
            self.events.append(ClaimEvent(now, "defended", source, f"0x{name_value:016X}"))
            self._send_claim(source)
            return
        self.events.append(ClaimEvent(now, "lost", source, f"0x{name_value:016X}"))
        if self.name.self_configurable:
            for candidate in SELF_CONFIGURABLE_RANGE:
                if candidate != source and self._is_free(candidate):
                    self.events.append(ClaimEvent(now, "moved", candidate))
                    self._claim(candidate, now)
                    return
        self._cannot_claim(now)

    def on_request(self, destination: int, now: float) -> None:
        """A request for the address-claimed PGN, to ``destination``."""
        if self.current is None:
            return
        if destination not in (GLOBAL_ADDRESS, self.current):
            return
        self.events.append(ClaimEvent(now, "answered-request", self.current))
        self._send_claim(self.current)

    def _claim(self, address: int, now: float) -> None:
        self.current = address
        self.settled = False
        self.settle_at = now + CLAIM_WAIT_S
        self.events.append(ClaimEvent(now, "claim", address))
        self._send_claim(address)

    def _cannot_claim(self, now: float) -> None:
        self.current = NULL_ADDRESS
        self.settled = False
        self.settle_at = float("inf")
        self.events.append(ClaimEvent(now, "cannot-claim", NULL_ADDRESS))
        self._send_claim(NULL_ADDRESS)

    def _send_claim(self, source: int) -> None:
        self._send(CLAIM_PRIORITY, PGN_ADDRESS_CLAIMED, source, GLOBAL_ADDRESS,
                   self.name.to_bytes())


class AddressTable:
    """Who holds which address on the bus (address -> NAME), from the claims seen."""

    def __init__(self) -> None:
        self._by_address: dict[int, int] = {}

    def on_claim(self, source: int, name_value: int) -> None:
        """Record a claim (or, from 0xFE, a cannot-claim: the NAME holds no address)."""
        for address, value in list(self._by_address.items()):
            if value == name_value and address != source:
                del self._by_address[address]      # the NAME moved
        if source == NULL_ADDRESS:
            return
        holder = self._by_address.get(source)
        if holder is not None and holder < name_value:
            return   # the lower NAME keeps the address; the newcomer will lose
        self._by_address[source] = name_value

    def forget(self, address: int) -> None:
        """Drop the entry of ``address``."""
        self._by_address.pop(address, None)

    def name_of(self, address: int) -> int | None:
        """The NAME holding ``address``, ``None`` if none."""
        return self._by_address.get(address)

    def snapshot(self) -> dict[int, int]:
        """A copy of the table (address -> NAME)."""
        return dict(self._by_address)
