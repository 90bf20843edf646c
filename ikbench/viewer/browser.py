"""Screenshots of a web page in headless Chromium, driven over the DevTools protocol.

``chromium --headless --screenshot`` fires after a *virtual* time budget and caught viser's
panel half laid out, so Chromium is started with ``--remote-debugging-port=0`` (it writes the
port it chose to ``<profile>/DevToolsActivePort``) and driven over the page's websocket with
the ``websockets`` package (a viser dependency): navigate, wait in real time until a text is
on the page, capture. DevTools methods used: ``Page.enable``, ``Page.navigate``,
``Emulation.setDeviceMetricsOverride``, ``Runtime.evaluate``, ``Page.captureScreenshot``,
``Input.dispatchMouseEvent`` (a drag).
"""

from __future__ import annotations

import base64
import io
import itertools
import json
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np

#: Flags for a machine without network or display: root needs --no-sandbox; the
#: background-networking flags stop Chromium's own connections.
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                  "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--hide-scrollbars")
#: Removes viser's "Software WebGL rendering detected" notice (shown under SwiftShader).
HIDE_SOFTWARE_GL_NOTICE = """(() => {
  for (const el of document.querySelectorAll('div')) {
    if (el.childElementCount === 0
        && el.textContent.trim() === 'Software WebGL rendering detected') {
      let box = el;
      while (box.parentElement && !/Notification-root/.test(box.className)) {
        box = box.parentElement;
      }
      (box.parentElement ? box : el).style.display = 'none';
      return true;
    }
  }
  return false;
})()"""


def rgb(png: bytes) -> np.ndarray:
    """(H, W, 3) int32 RGB of a PNG."""
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int32)


def changed_pixels(a: np.ndarray, b: np.ndarray, threshold: int = 30) -> int:
    """Pixels whose RGB differs by more than ``threshold`` (summed over channels)."""
    return int((np.abs(a - b).sum(axis=-1) > threshold).sum())


def find_chromium() -> str | None:
    """Path of a Chromium or Chrome binary on PATH, or None."""
    names = ("chromium", "chromium-browser", "google-chrome", "chrome")
    return next((path for name in names if (path := shutil.which(name))), None)


class HeadlessPage:
    """A page in a headless Chromium (a context manager); ``timings`` records
    ``browser_start`` and ``page_ready`` [s after creation]."""

    def __init__(self, url: str, *, width: int = 1280, height: int = 800,
                 timeout_s: float = 90.0, chromium: str | None = None) -> None:
        self.url, self.width, self.height, self.timeout_s = url, width, height, timeout_s
        self.chromium = chromium or find_chromium()
        if self.chromium is None:
            raise RuntimeError("no Chromium found (Debian: apt-get install -y chromium)")
        self.timings: dict[str, float] = {}
        self._t0 = time.perf_counter()
        self._profile = ""
        self._proc: subprocess.Popen | None = None
        self._ws: Any = None
        self._ids = itertools.count(1)

    def __enter__(self) -> HeadlessPage:
        try:
            self._start()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _start(self) -> None:
        from websockets.sync.client import connect

        self._profile = tempfile.mkdtemp(prefix="ikbench-chromium-")
        self._proc = subprocess.Popen(
            [str(self.chromium), *CHROMIUM_FLAGS, f"--user-data-dir={self._profile}",
             "--remote-debugging-port=0", f"--window-size={self.width},{self.height}",
             "about:blank"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = Path(self._profile) / "DevToolsActivePort"
        deadline = time.monotonic() + self.timeout_s
        while not (port_file.exists() and port_file.read_text().strip()):
            if self._proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("Chromium did not start its DevTools server")
            time.sleep(0.05)
        port = int(port_file.read_text().split()[0])
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as reply:
            page = next(t for t in json.load(reply) if t.get("type") == "page")
        self._ws = connect(page["webSocketDebuggerUrl"], max_size=64 * 2**20, open_timeout=10)
        self.timings["browser_start"] = time.perf_counter() - self._t0
        self.call("Page.enable")
        self.call("Emulation.setDeviceMetricsOverride", width=self.width, height=self.height,
                  deviceScaleFactor=1, mobile=False)
        self.call("Page.navigate", url=self.url)

    def call(self, method: str, timeout_s: float = 60.0, **params: Any) -> dict:
        """Send one DevTools command and return its result (events in between are skipped)."""
        msg_id = next(self._ids)
        self._ws.send(json.dumps({"id": msg_id, "method": method, "params": params}))
        deadline = time.monotonic() + timeout_s
        while True:
            reply = json.loads(self._ws.recv(timeout=max(deadline - time.monotonic(), 0.01)))
            if reply.get("id") == msg_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return result.get("result", {}).get("value")

    def wait_for_text(self, text: str) -> None:
        """Block until the page has loaded and ``text`` is in its visible text."""
        probe = ("document.readyState === 'complete' && document.body.innerText.includes("
                 f"{json.dumps(text)})")
        deadline = time.monotonic() + self.timeout_s
        while not self.evaluate(probe):
            if time.monotonic() > deadline:
                raise RuntimeError(f"{text!r} not on the page after {self.timeout_s} s")
            time.sleep(0.1)
        self.timings.setdefault("page_ready", time.perf_counter() - self._t0)

    def capture(self, path: str | Path | None = None) -> bytes:
        """PNG of the viewport (also written to ``path`` when given)."""
        self.evaluate(HIDE_SOFTWARE_GL_NOTICE)
        png = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        if path is not None:
            Path(path).write_bytes(png)
        return png

    def settled(self, path: str | Path | None = None, timeout_s: float = 90.0,
                tolerance_px: int = 100) -> np.ndarray:
        """(H, W, 3) RGB of the viewport once two captures in a row differ in fewer than
        ``tolerance_px`` pixels (software WebGL takes seconds to draw); the last capture
        after ``timeout_s``. ``path``: where the PNG goes."""
        previous, deadline = None, time.monotonic() + timeout_s
        while True:
            image = rgb(self.capture(path))
            if previous is not None and changed_pixels(image, previous) < tolerance_px:
                return image
            if time.monotonic() > deadline:
                return image
            previous = image
            time.sleep(0.5)

    def drag(self, x: float, y: float, dx: float, dy: float, steps: int = 20,
             pause_s: float = 0.05) -> None:
        """Press the left mouse button at (x, y) [px], move by (dx, dy) in ``steps`` steps
        and release: a drag, as a hand makes it (DevTools ``Input.dispatchMouseEvent``)."""
        self.call("Input.dispatchMouseEvent", type="mouseMoved", x=x, y=y)
        time.sleep(4 * pause_s)  # a hover the page sees before the press (a loaded machine
        # draws software WebGL at a few frames a second, and the gizmo picks on hover)
        self.call("Input.dispatchMouseEvent", type="mousePressed", x=x, y=y, button="left",
                  buttons=1, clickCount=1)
        time.sleep(4 * pause_s)
        for k in range(1, steps + 1):
            self.call("Input.dispatchMouseEvent", type="mouseMoved", x=x + dx * k / steps,
                      y=y + dy * k / steps, button="left", buttons=1)
            time.sleep(pause_s)
        self.call("Input.dispatchMouseEvent", type="mouseReleased", x=x + dx, y=y + dy,
                  button="left", buttons=0, clickCount=1)

    def close(self) -> None:
        """Close the session, end Chromium and remove its profile."""
        if self._ws is not None:
            self._ws.close()
            self._ws = None
        if self._proc is not None:
            self._proc.terminate()
            try:
                self._proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
            self._proc = None
        if self._profile:
            shutil.rmtree(self._profile, ignore_errors=True)
