"""The VT in the browser: the implement's live masks in a local web page, its keys pressable.

:class:`BrowserVt` serves, with aiohttp on a thread of its own, one self-contained page
(nothing fetched from outside) that shows the active working set's screen as the
:class:`~hil.isobus.vt.screens.ScreenRecorder` last drew it, refreshed when it changes, with
its soft keys and buttons as clickable areas. A click presses the key (held as long as the
mouse button was down, at least 0.1 s) through the VT's thread-safe
:meth:`~hil.isobus.vt.server.VirtualTerminalServer.post`, so the press happens in the run's
own time on the thread that runs the network. The page's routes:

- ``/``: the page;
- ``/state.json``: the screen's number, the working set, its masks, the hotspots (object id,
  kind, label, rectangle, enabled), the VT's last events;
- ``/screen.png``: the latest screen (a placeholder before an implement's pool is active);
- ``POST /press`` with ``{"id": object id, "hold_s": seconds}``: press a key or button.

It listens on 127.0.0.1 by default: a bench's VT is not a thing to put on a network.
"""

from __future__ import annotations

import asyncio
import io
import json
import threading
from dataclasses import asdict
from typing import Any

from aiohttp import web
from PIL import Image, ImageDraw

from hil.isobus.vt.operator import Operator
from hil.isobus.vt.screens import ScreenRecorder
from hil.isobus.vt.server import VirtualTerminalServer

MIN_HOLD_S = 0.1
MAX_HOLD_S = 10.0


def _placeholder(width: int, height: int) -> bytes:
    image = Image.new("RGB", (width, height), (64, 64, 64))
    ImageDraw.Draw(image).text((20, 20), "Waiting for an implement's object pool ...",
                               fill=(230, 230, 230))
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return buffer.getvalue()


PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>agrihil VT</title>
<link rel="icon" href="data:,">
<style>
body { font-family: sans-serif; margin: 16px; background: #f4f4f4; color: #222; }
#screen { position: relative; display: inline-block; border: 1px solid #888; }
#screen img { display: block; }
.hot { position: absolute; border: 2px solid transparent; background: transparent;
       cursor: pointer; padding: 0; }
.hot:hover { border-color: #36c; }
.hot.down { border-color: #c33; background: rgba(200, 50, 50, 0.15); }
.hot[disabled] { cursor: not-allowed; }
#status { margin: 8px 0; font-size: 14px; }
#events { font-size: 12px; color: #555; white-space: pre-line; }
</style>
</head>
<body>
<h1 style="font-size: 18px">agrihil Virtual Terminal</h1>
<div id="status">connecting ...</div>
<div id="screen"><img id="shot" alt="the VT's screen" src="screen.png?n=0"></div>
<div id="events"></div>
<script>
"use strict";
let shown = -1;
let downAt = {};
function hotspot(h) {
  const b = document.createElement("button");
  b.className = "hot";
  b.dataset.id = String(h.object_id);
  b.dataset.kind = h.kind;
  b.title = h.kind + " " + h.object_id + (h.label ? " (" + h.label + ")" : "");
  b.setAttribute("aria-label", b.title);
  b.style.left = h.x + "px"; b.style.top = h.y + "px";
  b.style.width = h.w + "px"; b.style.height = h.h + "px";
  if (!h.enabled) { b.disabled = true; }
  b.addEventListener("pointerdown", () => { downAt[h.object_id] = performance.now();
                                           b.classList.add("down"); });
  b.addEventListener("pointerup", () => release(h.object_id, b));
  b.addEventListener("pointerleave", () => { if (h.object_id in downAt) {
                                               release(h.object_id, b); } });
  b.addEventListener("keydown", (e) => { if (e.key === "Enter" || e.key === " ") {
    e.preventDefault(); press(h.object_id, 0.2); } });
  return b;
}
function release(id, b) {
  b.classList.remove("down");
  const start = downAt[id];
  delete downAt[id];
  if (start === undefined) { return; }
  press(id, (performance.now() - start) / 1000);
}
async function press(id, holdS) {
  const r = await fetch("press", {method: "POST", headers: {"Content-Type": "application/json"},
                                  body: JSON.stringify({id: id, hold_s: holdS})});
  const answer = await r.json();
  document.getElementById("status").dataset.lastPress = JSON.stringify(answer);
}
async function poll() {
  try {
    const r = await fetch("state.json", {cache: "no-store"});
    const s = await r.json();
    document.getElementById("status").textContent = s.status;
    document.getElementById("events").textContent = s.events.join("\\n");
    if (s.screen !== shown) {
      shown = s.screen;
      const img = document.getElementById("shot");
      img.src = "screen.png?n=" + s.screen;
      const box = document.getElementById("screen");
      box.querySelectorAll(".hot").forEach(e => e.remove());
      s.hotspots.forEach(h => box.appendChild(hotspot(h)));
      box.dataset.screen = String(s.screen);
    }
  } catch (e) {
    document.getElementById("status").textContent = "the VT is not answering";
  }
  setTimeout(poll, 250);
}
poll();
</script>
</body>
</html>
"""


class BrowserVt:
    """The browser VT's web server (see the module docstring).

    Parameters
    ----------
    vt : VirtualTerminalServer
        The VT.
    recorder : ScreenRecorder
        Draws the screens the page shows.
    host, port : str, int
        Where to listen (port 0: any free port; :attr:`url` says which).
    """

    def __init__(self, vt: VirtualTerminalServer, recorder: ScreenRecorder,
                 host: str = "127.0.0.1", port: int = 8080) -> None:
        self.vt = vt
        self.recorder = recorder
        self.host = host
        self.port = port
        self.operator = Operator(vt)
        self.presses: list[tuple[int, float]] = []
        o = vt.options
        self._placeholder = _placeholder(o.data_mask_px, o.data_mask_px)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://{self.host}:{self.port}/"

    # -- the routes ------------------------------------------------------------------------------

    def _latest(self) -> tuple[int, int, bytes, tuple[Any, ...]] | None:
        ws = self.vt.active_working_set
        if ws is None:
            return None
        latest = self.recorder.latest.get(ws.address)
        if latest is None:
            return None
        return (ws.address, *latest)

    async def _page(self, request: web.Request) -> web.Response:
        return web.Response(text=PAGE, content_type="text/html")

    async def _state(self, request: web.Request) -> web.Response:
        latest = self._latest()
        events = [f"{e.time_s:.1f} s  {e.kind}  {e.detail}" for e in self.vt.events[-8:]]
        if latest is None:
            body: dict[str, Any] = {"screen": 0, "status": "no implement's pool is active",
                                    "hotspots": [], "events": events}
        else:
            address, count, _png, spots = latest
            ws = self.vt.sessions.get(address)
            mask = ws.active_mask if ws is not None else None
            body = {"screen": count, "address": address, "mask": mask,
                    "status": f"working set at 0x{address:02X}, mask {mask}",
                    "hotspots": [asdict(h) for h in spots], "events": events}
        return web.json_response(body, headers={"Cache-Control": "no-store"})

    async def _screen(self, request: web.Request) -> web.Response:
        latest = self._latest()
        png = latest[2] if latest is not None else self._placeholder
        return web.Response(body=png, content_type="image/png",
                            headers={"Cache-Control": "no-store"})

    async def _press(self, request: web.Request) -> web.Response:
        try:
            data = json.loads(await request.text())
            object_id = int(data["id"])
            hold_s = float(data.get("hold_s", 0.2))
        except (ValueError, KeyError, TypeError) as exc:
            return web.json_response({"ok": False, "error": f"bad press: {exc}"}, status=400)
        latest = self._latest()
        known = latest is not None and any(h.object_id == object_id for h in latest[3])
        if not known:
            return web.json_response({"ok": False, "error": f"object {object_id} is not a key "
                                      f"or button on the screen"}, status=404)
        hold_s = min(max(hold_s, MIN_HOLD_S), MAX_HOLD_S)
        self.presses.append((object_id, hold_s))
        self.vt.post(lambda now: self.operator.press(object_id, now, hold_s))
        return web.json_response({"ok": True, "id": object_id, "hold_s": hold_s})

    # -- the thread ------------------------------------------------------------------------------

    def start(self) -> str:
        """Start listening (on a daemon thread); the page's URL.

        Raises
        ------
        OSError
            The address cannot be listened on (a port in use), naming it.
        """
        ready = threading.Event()
        app = web.Application()
        app.add_routes([web.get("/", self._page), web.get("/state.json", self._state),
                        web.get("/screen.png", self._screen), web.post("/press", self._press)])

        def run() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            asyncio.set_event_loop(loop)
            runner = web.AppRunner(app, access_log=None)
            try:
                loop.run_until_complete(runner.setup())
                site = web.TCPSite(runner, self.host, self.port)
                loop.run_until_complete(site.start())
                if runner.addresses:
                    self.port = int(runner.addresses[0][1])
            except BaseException as exc:   # handed to the starting thread
                self._error = exc
                ready.set()
                loop.run_until_complete(runner.cleanup())
                loop.close()
                return
            ready.set()
            try:
                loop.run_forever()
            finally:
                loop.run_until_complete(runner.cleanup())
                loop.close()

        self._thread = threading.Thread(target=run, name="browser-vt", daemon=True)
        self._thread.start()
        ready.wait(10.0)
        if self._error is not None:
            error = self._error
            raise OSError(f"browser VT: cannot listen on {self.host}:{self.port}: {error}")
        return self.url

    def stop(self) -> None:
        """Stop the server and its thread."""
        loop, thread = self._loop, self._thread
        if loop is not None and thread is not None and thread.is_alive():
            loop.call_soon_threadsafe(loop.stop)
            thread.join(10.0)
        self._thread = None
