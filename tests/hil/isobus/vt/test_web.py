"""The browser VT: its routes over HTTP, and the page in Chromium pressing a key."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any

import pytest

from hil.isobus.vt.bench import VtBench
from hil.isobus.vt.messages import KeyActivation
from hil.isobus.vt.screens import ScreenRecorder
from hil.isobus.vt.web import BrowserVt

from .pools import IDS, implement_pool


@pytest.fixture
def served() -> Iterator[tuple[VtBench, BrowserVt]]:
    bench = VtBench([implement_pool().to_bytes()])
    recorder = ScreenRecorder(bench.vt, None, min_interval_s=0.2)
    web = BrowserVt(bench.vt, recorder, port=0)
    web.start()
    try:
        yield bench, web
    finally:
        web.stop()


def get(url: str) -> tuple[str, bytes]:
    with urllib.request.urlopen(url, timeout=10) as r:
        return r.headers.get("Content-Type", ""), r.read()


def post(url: str, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
    request = urllib.request.Request(url, data=json.dumps(body).encode(), method="POST",
                                     headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as err:
        return err.code, json.loads(err.read())


def test_routes_before_and_after_the_pool(served: tuple[VtBench, BrowserVt]) -> None:
    bench, web = served
    kind, png = get(web.url + "screen.png")
    assert kind == "image/png" and png[:4] == b"\x89PNG"
    state = json.loads(get(web.url + "state.json")[1])
    assert state["screen"] == 0 and state["hotspots"] == []
    bench.run_until(3.0)
    state = json.loads(get(web.url + "state.json")[1])
    assert state["screen"] == 1 and state["mask"] == IDS.home
    spots = {h["object_id"]: h for h in state["hotspots"]}
    assert set(spots) == {IDS.key_master, IDS.key_settings, IDS.button}
    assert spots[IDS.key_master]["label"] == "Master" and spots[IDS.button]["kind"] == "button"
    page = get(web.url)[1].decode()
    assert "<script>" in page and "http" not in page.replace(web.url, "")
    status, answer = post(web.url + "press", {"id": IDS.key_master, "hold_s": 0.5})
    assert status == 200 and answer == {"ok": True, "id": IDS.key_master, "hold_s": 0.5}
    bench.run_for(1.0)
    assert bench.client is not None
    assert [k.activation for k in bench.client.keys] == [
        KeyActivation.PRESSED, KeyActivation.STILL_HELD, KeyActivation.STILL_HELD,
        KeyActivation.RELEASED]
    assert post(web.url + "press", {"id": 4321})[0] == 404
    assert post(web.url + "press", {"nope": 1})[0] == 400


def test_a_port_in_use_is_an_error_naming_it(served: tuple[VtBench, BrowserVt]) -> None:
    bench, web = served
    other = BrowserVt(bench.vt, web.recorder, port=web.port)
    with pytest.raises(OSError, match=f"cannot listen on 127.0.0.1:{web.port}"):
        other.start()


def test_the_page_in_chromium_shows_the_mask_and_presses_a_key(
        served: tuple[VtBench, BrowserVt]) -> None:
    from tests.browser.cdp import Chromium, find_chromium

    executable = find_chromium()
    if executable is None:
        pytest.skip("Chromium is not installed")
    bench, web = served
    bench.run_until(3.0)
    browser = Chromium(executable)
    try:
        browser.load(web.url, width=900, height=700)
        deadline = time.monotonic() + 10
        facts: dict[str, Any] = {}
        while time.monotonic() < deadline:
            facts = browser.evaluate("""(() => ({
              screen: document.getElementById('screen').dataset.screen,
              width: document.getElementById('shot').naturalWidth,
              keys: Array.from(document.querySelectorAll('.hot')).map(
                b => [b.dataset.id, b.dataset.kind, b.title]),
              status: document.getElementById('status').textContent}))()""")
            if facts.get("screen") == "1" and facts.get("width"):
                break
            time.sleep(0.1)
        assert facts["screen"] == "1" and facts["width"] == 564, facts
        assert [str(IDS.key_master), "key", f"key {IDS.key_master} (Master)"] in facts["keys"]
        assert f"mask {IDS.home}" in facts["status"]
        # a click on the Master key's area: pointer down, up
        browser.evaluate(f"""(() => {{
          const b = document.querySelector('.hot[data-id="{IDS.key_master}"]');
          b.dispatchEvent(new PointerEvent('pointerdown', {{bubbles: true}}));
          b.dispatchEvent(new PointerEvent('pointerup', {{bubbles: true}}));
        }})()""")
        deadline = time.monotonic() + 10
        while not web.presses and time.monotonic() < deadline:
            time.sleep(0.05)
        assert web.presses and web.presses[0][0] == IDS.key_master
        bench.run_for(0.5)
        assert bench.client is not None
        assert [(k.object_id, k.activation) for k in bench.client.keys] == [
            (IDS.key_master, KeyActivation.PRESSED), (IDS.key_master, KeyActivation.RELEASED)]
        assert browser.console_errors() == []
        outside = [u for u in browser.requested_urls() if not u.startswith(web.url)]
        assert outside == []
    finally:
        browser.close()


def test_attach_vt_to_a_tractor_network(tmp_path: Any) -> None:
    from hil.isobus.network import IsobusNetwork
    from hil.isobus.vt.attach import attach_vt
    from hil.isobus.vt.bench import IMPLEMENT_ADDRESS, IMPLEMENT_NAME
    from hil.isobus.vt.client import VtClient
    from hil.isobus.wire import VirtualWire

    tractor_network = IsobusNetwork(name="tractor")
    lines: list[str] = []
    attached = attach_vt(tractor_network, screens_dir=tmp_path / "vt", browser_port=0,
                         console=lines.append)
    try:
        implement = IsobusNetwork(name="implement")
        cf = implement.add(IMPLEMENT_NAME, IMPLEMENT_ADDRESS, "implement")
        cf.run(VtClient(cf, [implement_pool().to_bytes()]))
        VirtualWire([tractor_network, implement]).run_until(3.0)
        assert lines == [f"the VT in the browser: {attached.browser.url}"]  # type: ignore[union-attr]
        state = json.loads(get(attached.browser.url + "state.json")[1])  # type: ignore[union-attr]
        assert state["mask"] == IDS.home
    finally:
        path = attached.close()
    assert path is not None
    record = json.loads(path.read_text())
    assert record["working_sets"][0]["pool_bytes"] == implement_pool().size
    assert (tmp_path / "vt" / "screen-0001.png").is_file()
