"""What the depth rig checks before a run is held at a checkpoint and restores in a copy that
continues from it (:mod:`hil.rig.checkpoint`): the GNSS line's unread bytes, counted once the
kernel has moved them into the reader's queue."""

from __future__ import annotations

from plant_emulators.sowing_depth.gnss_serial import PtySerialPort


def test_settled_unread_bytes_counts_what_was_just_written() -> None:
    # FIONREAD alone missed bytes right after the write in 460 of 2,000 tries
    for _ in range(200):
        with PtySerialPort() as port:
            assert port.write(b"$GNRMC,x*00\r\n" * 10)
            assert port.settled_unread_bytes() == 130


def test_a_discarded_line_is_empty_once_settled() -> None:
    with PtySerialPort() as port:
        port.write(b"x" * 500)
        port.settled_unread_bytes()
        port.discard_unread()
        assert port.settled_unread_bytes() == 0
        assert port.write(b"y" * 10) and port.settled_unread_bytes() == 10


def test_a_closed_line_has_nothing_unread() -> None:
    port = PtySerialPort()
    port.write(b"x")
    port.close()
    assert port.settled_unread_bytes() == 0
