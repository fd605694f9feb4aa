"""The software bus's settings: ports, limits, busy polling, and the loopback-only rule.

Shared by the bus's modules (the core, the client session, the facade, the child process) so
that none of them has to import another just for a constant.
"""

from __future__ import annotations

import ipaddress
import os

from hil.errors import HilError

DEFAULT_PORT = 29536
DEFAULT_CHANNEL = "can0"
#: After ``< rawmode >`` the reply ``< ok >`` must reach the client alone (python-can reads it
#: with one exact ``recv``), so frames for a new client are held back this long, then flushed,
#: or until the client sends its next message (it has read ``< ok >`` by then; agrihil's own
#: clients send ``< echo >`` right after ``< rawmode >`` and so are never held).
RAWMODE_HOLD_S = 0.05
#: A client whose unsent bytes exceed this is too slow: frames for it are dropped and counted.
MAX_CLIENT_BUFFER = 4 * 1024 * 1024
#: Kernel send buffer per client socket: without a bound, loopback autotuning lets a client
#: that never reads hoard megabytes before the user-space bound above ever applies.
CLIENT_SNDBUF = 256 * 1024


class SoftwareBusError(HilError, OSError):
    """The software bus could not start or stopped abnormally."""


def check_loopback(host: str, allow_remote: bool) -> None:
    """Refuse to bind anything but loopback unless explicitly asked."""
    if allow_remote:
        return
    if host == "localhost":
        return
    try:
        if ipaddress.ip_address(host).is_loopback:
            return
    except ValueError:
        pass
    raise SoftwareBusError(
        f"refusing to bind the software bus to {host!r}: it is not a loopback address "
        "(pass allow_remote / --allow-remote to expose the bus on a network)")


#: Busy polling of a bus process (``hil bus serve``, :class:`SoftwareBusProcess`) after traffic,
#: upper bound of the adaptive window in µs (see :class:`hil.softbus.loop.BusyPoll`); the
#: environment variable overrides it, 0 turns it off. An embedded bus (:class:`SoftwareBus` in
#: a thread) does not busy poll unless asked: a spinning thread holds its process's GIL.
DEFAULT_BUSY_POLL_US = 200.0
BUSY_POLL_ENV = "AGRIHIL_SOFTBUS_BUSY_POLL_US"
#: A local driver (:meth:`SoftwareBus.local_bus`) that has not run the loop for this long hands
#: it back to the bus thread (so that other clients are served while the rig does something
#: else, e.g. restarts its DUT).
TAKEOVER_S = 0.02


def busy_poll_from_env(default: float) -> float:
    """The busy-poll limit in µs: ``AGRIHIL_SOFTBUS_BUSY_POLL_US`` if set, else ``default``."""
    text = os.environ.get(BUSY_POLL_ENV, "").strip()
    if not text:
        return default
    try:
        value = float(text)
    except ValueError as exc:
        raise SoftwareBusError(f"{BUSY_POLL_ENV}={text!r} is not a number of µs") from exc
    return max(0.0, value)

