"""The VT's non-volatile memory: stored pool versions per working set NAME.

A client stores its pool under a version label after a transfer (store version, 7 bytes, or
extended store version, 32 bytes) and on its next connection asks for the labels (get
versions) and loads one instead of uploading it again. :class:`VersionStore` keeps the
transfers as received; give the same store to a restarted VT (its flash), or a directory to
keep them on disk between runs (one file per NAME and label, the transfers with a 4-byte
length before each).
"""

from __future__ import annotations

from pathlib import Path

from hil.errors import ConfigError

ClientKey = int | tuple[str, int]
"""A working set master's NAME, or ``("address", sa)`` when the network does not know it."""


class VersionStore:
    """Stored versions: client -> label -> the pool's transfers."""

    def __init__(self, directory: Path | None = None) -> None:
        self.directory = directory
        self._versions: dict[ClientKey, dict[bytes, tuple[bytes, ...]]] = {}
        if directory is not None:
            self._load_directory(directory)

    def labels(self, client: ClientKey, extended: bool = False) -> list[bytes]:
        """The labels stored for ``client`` (7-byte ones, or 32-byte extended ones)."""
        size = 32 if extended else 7
        return [label for label in self._versions.get(client, {}) if len(label) == size]

    def load(self, client: ClientKey, label: bytes) -> tuple[bytes, ...] | None:
        """The transfers stored under ``label``, ``None`` if there are none."""
        return self._versions.get(client, {}).get(bytes(label))

    def store(self, client: ClientKey, label: bytes, transfers: tuple[bytes, ...]) -> None:
        """Keep ``transfers`` under ``label`` (replacing a version with the same label)."""
        self._versions.setdefault(client, {})[bytes(label)] = tuple(transfers)
        if self.directory is not None:
            self._write(client, bytes(label), transfers)

    def delete(self, client: ClientKey, label: bytes) -> bool:
        """Forget a version; whether there was one."""
        found = self._versions.get(client, {}).pop(bytes(label), None) is not None
        if found and self.directory is not None:
            path = self._path(client, bytes(label))
            path.unlink(missing_ok=True)
        return found

    # -- on disk ---------------------------------------------------------------------------------

    def _path(self, client: ClientKey, label: bytes) -> Path:
        assert self.directory is not None
        who = f"{client:016X}" if isinstance(client, int) else f"sa{client[1]:02X}"
        return self.directory / f"{who}-{label.hex()}.vtp"

    def _write(self, client: ClientKey, label: bytes, transfers: tuple[bytes, ...]) -> None:
        assert self.directory is not None
        self.directory.mkdir(parents=True, exist_ok=True)
        body = b"".join(len(t).to_bytes(4, "little") + t for t in transfers)
        path = self._path(client, label)
        tmp = path.with_suffix(".tmp")
        tmp.write_bytes(body)
        tmp.replace(path)

    def _load_directory(self, directory: Path) -> None:
        if not directory.is_dir():
            return
        for path in sorted(directory.glob("*.vtp")):
            try:
                who, label_hex = path.stem.split("-", 1)
                client: ClientKey = (("address", int(who[2:], 16)) if who.startswith("sa")
                                     else int(who, 16))
                label = bytes.fromhex(label_hex)
                body = path.read_bytes()
                transfers = []
                pos = 0
                while pos < len(body):
                    n = int.from_bytes(body[pos:pos + 4], "little")
                    if pos + 4 + n > len(body):
                        raise ValueError("cut short")
                    transfers.append(body[pos + 4:pos + 4 + n])
                    pos += 4 + n
            except ValueError as exc:
                raise ConfigError(f"not a stored VT pool version ({exc})",
                                  path=str(path)) from None
            self._versions.setdefault(client, {})[label] = tuple(transfers)
