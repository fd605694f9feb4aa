"""The software bus's control connection: who may send ``< hil … >`` commands, and the client.

Control commands (faults, error frames, statistics) change what every client of the bus sees,
so a frame client may not send them: a connection becomes a *control connection* by first
sending ``< hil control TOKEN >`` with the bus's control token, and only then may it send
``< hil … >`` commands. Any other connection that sends one gets ``< hil error … >`` and is
counted (``control_refused`` in the stats).

The token is random per bus (or given, :envvar:`AGRIHIL_SOFTBUS_CONTROL_TOKEN` for
``hil bus serve``). A bus that listens writes it to a file readable by its user only,
:func:`token_path` (``$XDG_RUNTIME_DIR/agrihil/`` or ``/tmp/agrihil-UID/``, one file per
port), and removes the file when it stops; ``hil bus fault``/``stats`` read it from there.
The token keeps the bus's controls away from the programs that only speak CAN to it (DUTs,
fuzzers, stray socketcand tools); it is no barrier to code running as the same user, which
can read the file.
"""

from __future__ import annotations

import contextlib
import hmac
import os
import secrets
import socket
import stat
import tempfile
from pathlib import Path

from hil.errors import BusError

#: ``hil bus serve`` takes its control token from here when it is set (what
#: :class:`~hil.softbus.process.SoftwareBusProcess` does); ``control`` falls back to it.
CONTROL_TOKEN_ENV = "AGRIHIL_SOFTBUS_CONTROL_TOKEN"


def new_token() -> str:
    """A fresh random control token (128 bits, hex)."""
    return secrets.token_hex(16)


def tokens_equal(given: str, expected: str) -> bool:
    """Compare tokens in constant time."""
    return hmac.compare_digest(given.encode("ascii", "replace"),
                               expected.encode("ascii", "replace"))


def _token_dir() -> Path:
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and Path(runtime).is_dir():
        return Path(runtime) / "agrihil"
    return Path(tempfile.gettempdir()) / f"agrihil-{os.getuid()}"


def token_path(port: int) -> Path:
    """Where the bus listening on ``port`` writes its control token."""
    return _token_dir() / f"softbus-{port}.token"


def _private_dir() -> Path:
    """The token directory, created 0700; refused if someone else owns it or may write it."""
    path = _token_dir()
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    info = path.lstat()
    if (not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid()
            or info.st_mode & (stat.S_IWGRP | stat.S_IWOTH)):
        raise OSError(f"{path} is not a private directory of this user")
    return path


def write_token(port: int, token: str) -> Path:
    """Write ``token`` for the bus on ``port`` (mode 0600, replaced atomically).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    OSError
        The directory is not private to this user, or the file cannot be written.
    """
    path = _private_dir() / f"softbus-{port}.token"
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".softbus-", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as out:
            out.write(token + "\n")
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return path


def remove_token(port: int, token: str) -> None:
    """Remove the token file of ``port`` if it still holds ``token`` (not a newer bus's)."""
    path = token_path(port)
    with contextlib.suppress(OSError):
        if tokens_equal(path.read_text().strip(), token):
            path.unlink()


def read_token(port: int) -> str | None:
    """The control token of the bus on ``port``: its file's, else the environment's, else None."""
    with contextlib.suppress(OSError):
        text = token_path(port).read_text().strip()
        if text:
            return text
    return os.environ.get(CONTROL_TOKEN_ENV) or None


def _read_messages(sock: socket.socket, n: int) -> list[bytes]:
    """Read until ``n`` whole ``< … >`` messages arrived (or the bus closes)."""
    data = b""
    while data.count(b">") < n:
        chunk = sock.recv(65536)
        if not chunk:
            break
        data += chunk
    return [part.strip() + b" >" for part in data.split(b">") if part.strip()]


def control(host: str, port: int, words: list[str], timeout: float = 5.0,
            token: str | None = None) -> str:
    """Send one ``< hil … >`` command to a running software bus and return its reply.

    Parameters
    ----------
    host, port
        Where the bus listens.
    words
        The command, e.g. ``["stats"]`` or ``["fault", "add", "drop", "id=0x181"]``.
    timeout
        Seconds to wait for the connection and for each reply.
    token
        The bus's control token; default: :func:`read_token` for ``port``.

    Returns
    -------
    str
        The reply message, e.g. ``"< hil ok 1 >"``.

    Raises
    ------
    BusError
        The bus cannot be reached, is not a software bus, or refused the token or the command.
    """
    token = token or read_token(port)
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            greeting = sock.recv(64)
            if not greeting.startswith(b"< hi >"):
                raise BusError(f"{host}:{port} is not a software bus (got {greeting!r})")
            if not token:
                raise BusError(f"no control token for the software bus on port {port}: the "
                               f"bus writes it to {token_path(port)} when it starts; pass "
                               f"--token or set {CONTROL_TOKEN_ENV}")
            sock.sendall(f"< hil control {token} >< hil {' '.join(words)} >".encode("ascii"))
            replies = _read_messages(sock, 2)
    except OSError as exc:
        raise BusError(f"cannot reach the software bus at {host}:{port}: {exc}") from exc
    texts = [r.decode("ascii", "replace") for r in replies]
    if not texts:
        raise BusError(f"the software bus at {host}:{port} closed the control connection")
    if texts[0].startswith("< hil error"):
        raise BusError(f"software bus refused the control connection: {texts[0][12:-2]}")
    if len(texts) < 2:
        raise BusError(f"the software bus at {host}:{port} did not answer "
                       f"'{' '.join(words)}'")
    text = texts[1]
    if text.startswith("< hil error"):
        raise BusError(f"software bus refused '{' '.join(words)}': {text[12:-2]}")
    return text
