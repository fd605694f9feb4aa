"""The software bus's control client: send one ``< hil … >`` command to a running bus.

``hil bus fault``/``stats`` and :meth:`SoftwareBusProcess.stats` use it; the bus core does not
import the CLI, the CLI imports this.
"""

from __future__ import annotations

import socket

from hil.errors import BusError


def control(host: str, port: int, words: list[str], timeout: float = 5.0) -> str:
    """Send one ``< hil … >`` command to a running software bus and return its reply.

    Parameters
    ----------
    host, port
        Where the bus listens.
    words
        The command, e.g. ``["stats"]`` or ``["fault", "add", "drop", "id=0x181"]``.
    timeout
        Seconds to wait for the connection and for the reply.

    Returns
    -------
    str
        The reply message, e.g. ``"< hil ok 1 >"``.

    Raises
    ------
    BusError
        The bus cannot be reached, is not a software bus, or refused the command.
    """
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            greeting = sock.recv(64)
            if not greeting.startswith(b"< hi >"):
                raise BusError(f"{host}:{port} is not a software bus (got {greeting!r})")
            sock.sendall(f"< hil {' '.join(words)} >".encode("ascii"))
            reply = b""
            while not reply.rstrip().endswith(b">"):
                chunk = sock.recv(65536)
                if not chunk:
                    break
                reply += chunk
    except OSError as exc:
        raise BusError(f"cannot reach the software bus at {host}:{port}: {exc}") from exc
    text = reply.decode("ascii").strip()
    if text.startswith("< hil error"):
        raise BusError(f"software bus refused '{' '.join(words)}': {text[12:-2]}")
    return text
