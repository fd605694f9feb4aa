"""The software bus's control commands (``< hil … >``): parse, bound, run.

Every argument is bounded so that no command can hold the event loop for long: ``errors N``
takes at most :data:`MAX_ERROR_FRAMES` and injects them in slices of :data:`ERROR_SLICE`,
each slice a turn of the loop, so frames of other clients and new connections are served in
between (the reply comes after the last slice). Fault rules are bounded by
:data:`hil.softbus.faults.MAX_RULES` and :data:`hil.softbus.faults.MAX_DELAY_S`.

Only a control connection reaches this module (see :mod:`hil.softbus.control`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from typing import TYPE_CHECKING

from hil.softbus.faults import FaultError, FaultRule
from hil.softbus.settings import DEFAULT_CHANNEL

if TYPE_CHECKING:
    from hil.softbus.core import BusCore

#: The most error frames one ``errors N`` command injects.
MAX_ERROR_FRAMES = 10_000
#: Error frames injected per turn of the event loop.
ERROR_SLICE = 256
CHANNEL_NAME = re.compile(r"[A-Za-z0-9_.-]{1,64}")
KNOWN = "fault add|clear|list, errors N [CHANNEL], stats"


def error_reply(message: str) -> str:
    """``< hil error … >`` with the message made safe for the protocol (no ``<``/``>``)."""
    return f"< hil error {message.replace('<', '(').replace('>', ')')} >"


def parse_errors(words: list[str]) -> tuple[int, str]:
    """The count and channel of ``errors [N [CHANNEL]]``, bounded.

    Raises
    ------
    ValueError
        N is not an integer within 1..MAX_ERROR_FRAMES, or the channel name is not valid.
    """
    if len(words) > 3:
        raise ValueError("usage: errors [N [CHANNEL]]")
    try:
        count = int(words[1]) if len(words) > 1 else 1
    except ValueError:
        raise ValueError(f"errors: N must be an integer, got {words[1]!r}") from None
    if not 1 <= count <= MAX_ERROR_FRAMES:
        raise ValueError(f"errors: N must be within 1..{MAX_ERROR_FRAMES}, got {count}")
    channel = words[2] if len(words) > 2 else DEFAULT_CHANNEL
    if not CHANNEL_NAME.fullmatch(channel):
        raise ValueError(f"errors: bad channel name {channel!r}")
    return count, channel


def run(core: BusCore, words: list[str], reply: Callable[[str], None],
        alive: Callable[[], bool] = lambda: True) -> None:
    """Run one control command on ``core`` and pass its reply to ``reply``.

    Parameters
    ----------
    core
        The bus.
    words
        The command's words (what follows ``hil``).
    reply
        Called once with the reply message, at once or, for ``errors``, after the last slice.
    alive
        Checked before each slice of a long command: when it turns False (the control
        connection closed), the rest is abandoned.
    """
    try:
        if words[:1] == ["errors"]:
            count, channel = parse_errors(words)
            _errors_in_slices(core, count, channel, reply, alive)
            return
        reply(_run_now(core, words))
    except (FaultError, ValueError, IndexError) as exc:
        reply(error_reply(str(exc)))


def _errors_in_slices(core: BusCore, count: int, channel: str,
                      reply: Callable[[str], None], alive: Callable[[], bool]) -> None:
    def step(left: int) -> None:
        if not alive():
            return
        n = left if core.loop is None else min(left, ERROR_SLICE)
        core.inject_errors(n, channel)
        if left > n:
            core.call_later(0.0, step, left - n)
        else:
            reply("< hil ok >")

    step(count)


def _run_now(core: BusCore, words: list[str]) -> str:
    if words[:2] == ["fault", "add"]:
        rule_id = core.faults.add(FaultRule.parse(words[2:]))
        return f"< hil ok {rule_id} >"
    if words[:2] == ["fault", "clear"]:
        if len(words) > 3:
            raise ValueError("usage: fault clear [RULE]")
        core.faults.clear(int(words[2]) if len(words) > 2 else None)
        return "< hil ok >"
    if words == ["fault", "list"]:
        rules = {rid: " ".join(r.to_words()) for rid, r in core.faults.rules().items()}
        return f"< hil faults {json.dumps(rules)} >"
    if words == ["stats"]:
        return f"< hil stats {json.dumps(core.stats_dict())} >"
    raise ValueError(f"unknown hil command {' '.join(words)[:60]!r}; known: {KNOWN}")
