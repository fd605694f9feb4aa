"""Warnings about clients, logged once per address and then rate-limited.

A client that misbehaves, reconnects and misbehaves again must not fill the log: the first
warning from an address is logged, later ones at most once per interval each, with the count
of those held back in between. The state is kept per address (host, not host:port), so a
reconnect does not reset it, and for a bounded number of addresses (least recently warned
forgotten first).
"""

from __future__ import annotations

import logging
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class _State:
    last: float
    held: int = 0


class AddressWarnings:
    """Rate-limited warnings keyed by client address.

    Parameters
    ----------
    logger
        Where the warnings go.
    interval_s
        After the first warning from an address, at most one more per this many seconds.
    max_addresses
        How many addresses to remember (the least recently warned is forgotten first).
    clock
        A monotonic clock in seconds (tests pass a fake one).
    """

    def __init__(self, logger: logging.Logger, *, interval_s: float = 60.0,
                 max_addresses: int = 1024,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.logger = logger
        self.interval_s = interval_s
        self.max_addresses = max_addresses
        self.clock = clock
        self.suppressed = 0
        self._states: OrderedDict[str, _State] = OrderedDict()

    def warn(self, address: str, message: str, *args: object) -> bool:
        """Log ``message % args`` for ``address`` unless it is within its quiet interval.

        Returns
        -------
        bool
            Whether the warning was logged.
        """
        now = self.clock()
        state = self._states.get(address)
        if state is not None:
            self._states.move_to_end(address)
            if now - state.last < self.interval_s:
                state.held += 1
                self.suppressed += 1
                return False
            held, state.held, state.last = state.held, 0, now
            if held:
                message += f" ({held} similar warnings from {address} held back before this)"
        else:
            self._states[address] = _State(now)
            if len(self._states) > self.max_addresses:
                self._states.popitem(last=False)
        self.logger.warning(message, *args)
        return True
