"""The TC's non-volatile store of device descriptor object pools, per client NAME.

A client that finds its pool already known (same structure and localization labels) skips the
transfer and activates the stored one. The store outlives a server restart: pass the same
:class:`PoolStore` to the new server.

It is bounded, as a TC's non-volatile memory is: at most :data:`MAX_CLIENTS` clients (the one
stored longest ago makes room) and :data:`MAX_POOLS_PER_CLIENT` pools each, so peers that claim
NAME after NAME and activate pools cannot grow it without end.
"""

from __future__ import annotations

from dataclasses import dataclass

from hil.isobus.ddop import ObjectPool

MAX_CLIENTS = 64
"""Clients whose pools the store keeps."""
MAX_POOLS_PER_CLIENT = 8
"""Pools (structure labels) kept per client; the oldest goes first."""

ClientKey = int | tuple[str, int]
"""A client's NAME, or ``("address", sa)`` when the network layer does not know the NAME."""


@dataclass(frozen=True)
class StoredPool:
    """One stored pool with the labels a client asks for."""

    pool: ObjectPool
    raw: bytes

    @property
    def structure_label(self) -> bytes:
        """The device object's 7-byte structure label."""
        return self.pool.device.structure_label

    @property
    def extended_structure_label(self) -> bytes:
        """The version 4 extended structure label (empty before version 4)."""
        return self.pool.device.extended_structure_label

    @property
    def localization_label(self) -> bytes:
        """The device object's 7-byte localization label."""
        return self.pool.device.localization_label


class PoolStore:
    """Activated pools, newest last, per client."""

    def __init__(self) -> None:
        self._pools: dict[ClientKey, list[StoredPool]] = {}

    def latest(self, client: ClientKey) -> StoredPool | None:
        """The most recently activated pool of ``client``."""
        pools = self._pools.get(client)
        return pools[-1] if pools else None

    def by_structure(self, client: ClientKey, label: bytes, extended: bytes = b"",
                     ) -> StoredPool | None:
        """The stored pool of ``client`` with this structure label (and extended label)."""
        for stored in reversed(self._pools.get(client, [])):
            if stored.structure_label == label and (
                    not extended or stored.extended_structure_label == extended):
                return stored
        return None

    def by_localization(self, client: ClientKey, label: bytes) -> StoredPool | None:
        """The stored pool of ``client`` with this localization label."""
        for stored in reversed(self._pools.get(client, [])):
            if stored.localization_label == label:
                return stored
        return None

    def put(self, client: ClientKey, pool: ObjectPool, raw: bytes) -> None:
        """Store an activated pool (replacing one with the same structure labels)."""
        pools = [p for p in self._pools.get(client, [])
                 if (p.structure_label, p.extended_structure_label)
                 != (pool.device.structure_label, pool.device.extended_structure_label)]
        pools.append(StoredPool(pool, bytes(raw)))
        del pools[:-MAX_POOLS_PER_CLIENT]
        self._pools.pop(client, None)           # the newest client last
        self._pools[client] = pools
        while len(self._pools) > MAX_CLIENTS:
            del self._pools[next(iter(self._pools))]

    def delete(self, client: ClientKey) -> bool:
        """Forget every pool of ``client``; whether there was one."""
        return self._pools.pop(client, None) is not None

    def clients(self) -> list[ClientKey]:
        """Clients with a stored pool."""
        return list(self._pools)
