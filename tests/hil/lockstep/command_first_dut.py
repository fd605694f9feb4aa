"""A DUT that sends its command frame first in each step, then its status and heartbeat.

The reference fertilizer daemon (``reference_controllers.daemon``) with its controller's answer
to each SYNC reordered: the command frames (ids given first on the command line) go first, the
rest after them in their own order. With ``--mark-steps`` it ends each step with the step-end
frame, as a DUT that sends its command first must in lockstep (docs/guide/clocks.md)::

    python tests/hil/lockstep/command_first_dut.py 0x220 --controller fertilizer-piecewise-pid \\
        --bus socketcand:127.0.0.1:29536/can0 --sync --mark-steps
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import can

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))   # the project root

from reference_controllers import daemon


class CommandFirst:
    """A controller whose every answer lists the command frames first."""

    def __init__(self, inner: Any, command_ids: frozenset[int]) -> None:
        self.inner = inner
        self.command_ids = command_ids

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def on_frame(self, msg: can.Message) -> list[can.Message]:
        out = self.inner.on_frame(msg)
        return sorted(out, key=lambda m: m.arbitration_id not in self.command_ids)


def main(argv: list[str]) -> int:
    command_ids = frozenset(int(word, 0) for word in argv[0].split(","))
    make = daemon.make_controller
    daemon.make_controller = lambda *a, **kw: CommandFirst(make(*a, **kw), command_ids)
    return daemon.main(argv[1:])


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
