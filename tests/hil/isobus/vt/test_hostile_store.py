"""The VT's version store and records under a hostile working set, without a network: bounded
versions and bytes (refused, nothing changed), a disk that refuses, labels that look like
paths, and the records that keep their first and latest entries."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.errors import ConfigError
from hil.isobus.vt.bounded import BoundedLog
from hil.isobus.vt.server import VtOptions
from hil.isobus.vt.store import StoreError, StoreFull, StoreLimits, VersionStore, stored_size

NAME = 0xA000_8000_0000_0092
POOL = (b"\x01" * 100, b"\x02" * 50)


def test_versions_past_a_names_bound_are_refused_and_nothing_changes(tmp_path: Path) -> None:
    store = VersionStore(tmp_path)
    limits = StoreLimits(max_versions_per_name=3)
    for k in range(3):
        store.store(NAME, b"V%06d" % k, POOL, limits)
    with pytest.raises(StoreFull, match="keeps 3 versions"):
        store.store(NAME, b"V000099", POOL, limits)
    store.store(NAME, b"V000001", POOL[:1], limits)     # replacing one is no new version
    assert store.count == 3 and len(list(tmp_path.iterdir())) == 3
    assert store.bytes == 2 * stored_size(POOL) + stored_size(POOL[:1])
    # another NAME has its own
    store.store(NAME + 1, b"V000000", POOL, limits)
    assert store.count == 4


def test_the_store_bounds_its_bytes_and_its_versions_in_all(tmp_path: Path) -> None:
    store = VersionStore(tmp_path)
    size = stored_size(POOL)
    with pytest.raises(StoreFull, match="bytes"):
        store.store(NAME, b"BIG    ", POOL, StoreLimits(max_bytes=size - 1))
    assert store.count == 0 and list(tmp_path.iterdir()) == []
    limits = StoreLimits(max_versions=2)
    store.store(NAME, b"A      ", POOL, limits)
    store.store(NAME + 1, b"A      ", POOL, limits)
    with pytest.raises(StoreFull, match="the store keeps 2 versions"):
        store.store(NAME + 2, b"A      ", POOL, limits)
    assert store.delete(NAME, b"A      ")
    store.store(NAME + 2, b"A      ", POOL, limits)
    assert store.bytes == 2 * size
    # read back from the directory, the same versions and bytes
    again = VersionStore(tmp_path)
    assert again.count == 2 and again.bytes == 2 * size


def test_the_same_version_stored_again_is_not_written_again(tmp_path: Path) -> None:
    store = VersionStore(tmp_path)
    store.store(NAME, b"SAME   ", POOL)
    path = next(tmp_path.iterdir())
    path.write_bytes(b"")       # a write would put the version back
    store.store(NAME, b"SAME   ", POOL)
    assert path.read_bytes() == b""


def test_labels_with_path_characters_stay_hex_file_names(tmp_path: Path) -> None:
    store = VersionStore(tmp_path / "store")
    labels = [b"../../x", b"/etc/pa", b"\x00" * 7, b"..\\..\\"[:7].ljust(7), b"../" * 10 + b".."]
    for label in labels:
        store.store(NAME, label, POOL)
    files = sorted(p for p in tmp_path.rglob("*") if p.is_file())
    assert [f.parent for f in files] == [tmp_path / "store"] * len(labels)
    assert {f.name.split("-", 1)[1][:-4] for f in files} == {label.hex() for label in labels}
    again = VersionStore(tmp_path / "store")
    assert sorted(again.labels(NAME) + again.labels(NAME, extended=True)) == sorted(labels)


def test_a_label_that_is_not_7_or_32_bytes_is_refused() -> None:
    with pytest.raises(ValueError, match="7 or 32"):
        VersionStore().store(NAME, b"x" * 40, POOL)


def test_a_disk_that_refuses_is_a_store_error_and_the_version_is_not_kept(tmp_path: Path,
                                                                           ) -> None:
    (tmp_path / "file").write_text("in the way")
    store = VersionStore(tmp_path / "file" / "store")
    with pytest.raises(StoreError, match="cannot write"):
        store.store(NAME, b"DISK   ", POOL)
    assert store.count == 0 and store.bytes == 0 and store.load(NAME, b"DISK   ") is None


def test_a_stored_file_with_a_label_of_another_length_is_a_config_error(tmp_path: Path) -> None:
    (tmp_path / f"{NAME:016X}-{b'abc'.hex()}.vtp").write_bytes(b"")
    with pytest.raises(ConfigError, match="label of 3 bytes"):
        VersionStore(tmp_path)


def test_the_vt_options_carry_the_store_limits() -> None:
    options = VtOptions(store_max_bytes=1000, store_max_versions=5,
                        store_max_versions_per_name=2)
    assert options.store_limits == StoreLimits(1000, 5, 2)
    with pytest.raises(ValueError, match="max_versions_per_name"):
        VtOptions(store_max_versions_per_name=0)


def test_a_bounded_log_keeps_its_first_entries_and_its_latest() -> None:
    log: BoundedLog[int] = BoundedLog(100)
    for k in range(10_000):
        log.append(k)
    assert len(log) <= 100 and log.total == 10_000 and log.omitted == 10_000 - len(log)
    assert log[:25] == list(range(25))
    assert log[-1] == 9_999 and log[-8:] == list(range(9_992, 10_000))
    assert log == sorted(log)
