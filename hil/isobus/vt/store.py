"""The VT's non-volatile memory: stored pool versions per working set NAME.

A client stores its pool under a version label after a transfer (store version, 7 bytes, or
extended store version, 32 bytes) and on its next connection asks for the labels (get
versions) and loads one instead of uploading it again. :class:`VersionStore` keeps the
transfers as received; give the same store to a restarted VT (its flash), or a directory to
keep them on disk between runs (one file per NAME and label, the transfers with a 4-byte
length before each).

A working set's label never becomes a path: a file is named by the NAME in hex and the label's
bytes in hex, so a label of ``../../x`` or ``/etc`` stays a file name inside the directory. The
store is bounded (:class:`StoreLimits`: bytes and versions in all, versions per NAME): a
version beyond a bound is refused (:class:`StoreFull`, which the VT answers with the store
version response's "insufficient memory" bit), so a peer storing thousands of versions cannot
fill the disk; a disk that refuses a write is a :class:`StoreError` ("any other error"), not
the end of the VT.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path

from hil.errors import ConfigError

ClientKey = int | tuple[str, int]
"""A working set master's NAME (``("address", sa)``: a version kept by an older rig for an
address whose NAME it did not know; the VT stores under NAMEs only)."""

LABEL_LENGTHS = (7, 32)
"""Bytes of a version label and of an extended version label."""


@dataclass(frozen=True)
class StoreLimits:
    """How much the store keeps (each bound > 0).

    Attributes
    ----------
    max_bytes : int
        Bytes of all versions together, as stored (the transfers with 4 bytes before each).
    max_versions : int
        Versions of all NAMEs together (files on disk).
    max_versions_per_name : int
        Versions one working set NAME may keep.
    """

    max_bytes: int = 64 * 1024 * 1024
    max_versions: int = 256
    max_versions_per_name: int = 32

    def __post_init__(self) -> None:
        for key in ("max_bytes", "max_versions", "max_versions_per_name"):
            if getattr(self, key) <= 0:
                raise ValueError(f"version store {key} = {getattr(self, key)}: must be > 0")


class StoreFull(Exception):
    """A version the store's limits leave no room for (the message says which bound)."""


class StoreError(Exception):
    """The disk refused to keep or remove a version (the message names the file)."""


def stored_size(transfers: tuple[bytes, ...]) -> int:
    """Bytes a version takes in the store (its file's size)."""
    return sum(4 + len(t) for t in transfers)


class VersionStore:
    """Stored versions: client -> label -> the pool's transfers."""

    def __init__(self, directory: Path | None = None) -> None:
        self.directory = directory
        self._versions: dict[ClientKey, dict[bytes, tuple[bytes, ...]]] = {}
        #: bytes of every version kept (as on disk)
        self.bytes = 0
        if directory is not None:
            self._load_directory(directory)

    @property
    def count(self) -> int:
        """Versions kept, of all clients."""
        return sum(len(v) for v in self._versions.values())

    def labels(self, client: ClientKey, extended: bool = False) -> list[bytes]:
        """The labels stored for ``client`` (7-byte ones, or 32-byte extended ones)."""
        size = 32 if extended else 7
        return [label for label in self._versions.get(client, {}) if len(label) == size]

    def load(self, client: ClientKey, label: bytes) -> tuple[bytes, ...] | None:
        """The transfers stored under ``label``, ``None`` if there are none."""
        return self._versions.get(client, {}).get(bytes(label))

    def store(self, client: ClientKey, label: bytes, transfers: tuple[bytes, ...],
              limits: StoreLimits | None = None) -> None:
        """Keep ``transfers`` under ``label`` (replacing a version with the same label).

        Raises
        ------
        ValueError
            A label that is not 7 or 32 bytes.
        StoreFull
            No room within ``limits`` (nothing is changed).
        StoreError
            The disk refused the write (the version is not kept).
        """
        label, transfers = bytes(label), tuple(bytes(t) for t in transfers)
        if len(label) not in LABEL_LENGTHS:
            raise ValueError(f"a version label is 7 or 32 bytes, not {len(label)}")
        mine = self._versions.get(client, {})
        old = mine.get(label)
        if old == transfers:
            return                      # the same version again: nothing to write
        limits = limits or StoreLimits()
        size = stored_size(transfers)
        freed = stored_size(old) if old is not None else 0
        if self.bytes - freed + size > limits.max_bytes:
            raise StoreFull(f"{size} bytes: {self.bytes - freed} of the store's "
                            f"{limits.max_bytes} are taken")
        if old is None and len(mine) >= limits.max_versions_per_name:
            raise StoreFull(f"this NAME keeps {len(mine)} versions, the most one may")
        if old is None and self.count >= limits.max_versions:
            raise StoreFull(f"the store keeps {self.count} versions, the most it may")
        if self.directory is not None:
            self._write(client, label, transfers)
        self._versions.setdefault(client, {})[label] = transfers
        self.bytes += size - freed

    def delete(self, client: ClientKey, label: bytes) -> bool:
        """Forget a version; whether there was one.

        Raises
        ------
        StoreError
            The disk refused to remove its file (the version is kept).
        """
        label = bytes(label)
        old = self._versions.get(client, {}).get(label)
        if old is None:
            return False
        if self.directory is not None:
            path = self._path(client, label)
            try:
                path.unlink(missing_ok=True)
            except OSError as exc:
                raise StoreError(f"cannot remove {path}: {exc.strerror or exc}") from None
        del self._versions[client][label]
        if not self._versions[client]:
            del self._versions[client]
        self.bytes -= stored_size(old)
        return True

    # -- on disk ---------------------------------------------------------------------------------

    def _path(self, client: ClientKey, label: bytes) -> Path:
        assert self.directory is not None
        who = f"{client:016X}" if isinstance(client, int) else f"sa{client[1]:02X}"
        return self.directory / f"{who}-{label.hex()}.vtp"

    def _write(self, client: ClientKey, label: bytes, transfers: tuple[bytes, ...]) -> None:
        assert self.directory is not None
        body = b"".join(len(t).to_bytes(4, "little") + t for t in transfers)
        path = self._path(client, label)
        tmp = path.with_suffix(".tmp")
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            tmp.write_bytes(body)
            tmp.replace(path)
        except OSError as exc:
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)
            raise StoreError(f"cannot write {path}: {exc.strerror or exc}") from None

    def _load_directory(self, directory: Path) -> None:
        if not directory.is_dir():
            return
        for path in sorted(directory.glob("*.vtp")):
            try:
                who, label_hex = path.stem.split("-", 1)
                client: ClientKey = (("address", int(who[2:], 16)) if who.startswith("sa")
                                     else int(who, 16))
                label = bytes.fromhex(label_hex)
                if len(label) not in LABEL_LENGTHS:
                    raise ValueError(f"a label of {len(label)} bytes")
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
            self.bytes += stored_size(tuple(transfers))
