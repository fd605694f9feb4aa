"""The VT on a tractor's network, with its screens and the browser page: one call.

``hil isobus serve --vt`` (and any run that wants the VT beside the TC) does::

    attached = attach_vt(tractor.network, screens_dir=out / "vt", browser_port=8080)
    try:
        ...                                   # run the network
    finally:
        attached.close()                      # stops the page, writes vt/vt.json

The VT is :func:`~hil.isobus.vt.server.add_vt`'s; the screens are drawn into ``screens_dir``
(:class:`~hil.isobus.vt.screens.ScreenRecorder`) and the VT's record written there at the end;
with ``browser_port`` the browser VT (:class:`~hil.isobus.vt.web.BrowserVt`) serves them live.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hil.isobus.network import IsobusNetwork
from hil.isobus.vt.screens import ScreenRecorder, vt_record
from hil.isobus.vt.server import VirtualTerminalServer, VtOptions, add_vt
from hil.isobus.vt.store import VersionStore
from hil.isobus.vt.web import BrowserVt


@dataclass
class AttachedVt:
    """The VT, its recorder, and the browser page when one was asked for."""

    vt: VirtualTerminalServer
    recorder: ScreenRecorder
    browser: BrowserVt | None
    screens_dir: Path | None

    def close(self, write: bool | None = None) -> Path | None:
        """Stop the browser page; write ``vt.json`` into the screens directory (its path).

        ``write=None``: only if the VT took its address (the network ran: a serve whose bus
        could not be opened leaves nothing behind)."""
        if self.browser is not None:
            self.browser.stop()
        if write is None:
            write = self.vt.port.address is not None
        if self.screens_dir is None or not write:
            return None
        self.screens_dir.mkdir(parents=True, exist_ok=True)
        path = self.screens_dir / "vt.json"
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(vt_record(self.vt, self.recorder), indent=1),
                       encoding="utf-8")
        tmp.replace(path)
        return path


def attach_vt(network: IsobusNetwork, *, options: VtOptions | None = None,
              store: VersionStore | None = None, screens_dir: Path | None = None,
              browser_port: int | None = None, browser_host: str = "127.0.0.1",
              min_interval_s: float = 0.2,
              console: Callable[[str], None] | None = print) -> AttachedVt:
    """Put the VT on ``network``, draw its screens, serve the browser page if asked.

    Raises
    ------
    OSError
        The browser page's port cannot be listened on (naming it).
    """
    vt = add_vt(network, options, store)
    recorder = ScreenRecorder(vt, screens_dir, min_interval_s=min_interval_s)
    browser = None
    if browser_port is not None:
        browser = BrowserVt(vt, recorder, browser_host, browser_port)
        url = browser.start()
        if console is not None:
            console(f"the VT in the browser: {url}")
    return AttachedVt(vt, recorder, browser, screens_dir)
