"""Headless Chromium driven over the DevTools protocol (CDP), for the explorer's browser test and benchmark.

``open_page(exe, url, home)`` starts Chromium (SwiftShader WebGL; every host but 127.0.0.1 unreachable: a dead
proxy and a resolver that finds nothing), connects to its first tab's DevTools websocket with aiohttp, enables
the Network domain (every request URL is recorded in ``Page.requests``) and navigates to ``url``.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest


class Page:
    """One Chromium tab: ``call(method, **params)``, ``js(expression)`` (promises awaited), ``wait(expr)``."""

    def __init__(self, ws, loop) -> None:
        self.ws, self.loop, self.n, self.requests = ws, loop, 0, []

    async def _call(self, method: str, params: dict) -> dict:
        self.n += 1
        await self.ws.send_json({"id": self.n, "method": method, "params": params})
        while True:
            msg = await self.ws.receive_json(timeout=120)
            if msg.get("method") == "Network.requestWillBeSent":
                self.requests.append(msg["params"]["request"]["url"])
            if msg.get("id") == self.n:
                if "error" in msg:
                    raise AssertionError(f"{method}: {msg['error']}")
                return msg["result"]

    def call(self, method: str, **params) -> dict:
        return self.loop.run_until_complete(self._call(method, params))

    def js(self, expression: str):
        res = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in res:
            raise AssertionError(f"{expression}: {res['exceptionDetails']}")
        return res["result"].get("value")

    def wait(self, expression: str, timeout_s: float = 60.0):
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            value = self.js(expression)
            if value:
                return value
            self.loop.run_until_complete(asyncio.sleep(0.1))
        raise AssertionError(f"timed out waiting for {expression}")


@contextlib.contextmanager
def open_page(exe: str, url: str, home: Path) -> Iterator[Page]:
    """A Chromium tab on ``url`` (profile and HOME under ``home``); Chromium is killed on exit."""
    import aiohttp

    profile = home / "profile"
    browser = subprocess.Popen(
        [exe, "--headless", "--no-sandbox", "--disable-dev-shm-usage", "--no-first-run",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--proxy-server=127.0.0.1:9",
         "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1", "--window-size=1400,1000",
         "--remote-debugging-port=0", f"--user-data-dir={profile}", "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env={**os.environ, "HOME": str(home)})
    loop = asyncio.new_event_loop()
    session = ws = None
    try:
        port_file = profile / "DevToolsActivePort"
        end = time.monotonic() + 60
        while not port_file.is_file() or not port_file.read_text().strip():
            if time.monotonic() > end or browser.poll() is not None:
                raise AssertionError("Chromium did not start")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])

        async def connect():
            s = aiohttp.ClientSession()
            async with s.get(f"http://127.0.0.1:{port}/json/list") as r:
                targets = await r.json(content_type=None)
            tab = next(t for t in targets if t["type"] == "page")
            return s, await s.ws_connect(tab["webSocketDebuggerUrl"], max_msg_size=0)

        session, ws = loop.run_until_complete(connect())
        page = Page(ws, loop)
        page.call("Network.enable")
        page.call("Page.enable")
        page.call("Page.navigate", url=url)
        yield page
    finally:
        if ws is not None:
            loop.run_until_complete(ws.close())
        if session is not None:
            loop.run_until_complete(session.close())
        browser.kill()
        browser.wait()
        loop.close()


def chromium() -> str:
    """Path of a Chromium executable, or fail pointing to tools/ensure_chromium.sh."""
    exe = os.environ.get("CADFEAT_CHROMIUM", "").strip()
    if exe and Path(exe).is_file():
        return exe
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    pytest.fail("no headless Chromium for the report test: run tools/ensure_chromium.sh (installs Debian's "
                "chromium) or set CADFEAT_CHROMIUM to a Chromium/Chrome executable")
