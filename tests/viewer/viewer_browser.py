"""A headless Chromium for the viewer tests: open a page, take a screenshot (DevTools protocol).

Chromium renders WebGL in software (SwiftShader), so the screenshots are those a user would
see, without a GPU. One browser serves a whole test module; every call is bounded in time.
"""

from __future__ import annotations

import base64
import io
import itertools
import json
import os
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np

CHROMIUM = next((p for p in (os.environ.get("RATECTL_CHROMIUM"), "/usr/bin/chromium",
                             shutil.which("chromium"), shutil.which("chromium-browser"),
                             shutil.which("google-chrome")) if p and Path(p).is_file()), None)

FLAGS = ["--headless", "--no-sandbox", "--use-gl=angle", "--use-angle=swiftshader",
         "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--no-first-run", "--hide-scrollbars", "--mute-audio"]

# the "software WebGL" notice viser shows on SwiftShader covers part of the scene
_HIDE_NOTICES = ("document.querySelectorAll('.mantine-Notifications-root, .mantine-Notification-root')"
                 ".forEach(e => e.remove()); true")


class Browser:
    """One headless Chromium page driven over the DevTools protocol."""

    def __init__(self, *, width: int = 1000, height: int = 700, timeout: float = 20.0) -> None:
        import websockets.sync.client as wsc

        assert CHROMIUM is not None
        self._dir = tempfile.mkdtemp(prefix="ratectl-chromium-")
        self.width, self.height = width, height
        self._proc = subprocess.Popen(
            [CHROMIUM, *FLAGS, f"--user-data-dir={self._dir}", "--remote-debugging-port=0",
             f"--window-size={width},{height}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = Path(self._dir) / "DevToolsActivePort"
        deadline = time.monotonic() + timeout
        while not (port_file.is_file() and port_file.read_text().strip()):
            if time.monotonic() > deadline or self._proc.poll() is not None:
                self.close()
                raise RuntimeError("chromium did not start (no DevToolsActivePort)")
            time.sleep(0.05)
        port = int(port_file.read_text().split()[0])
        pages = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json", timeout=timeout))
        ws = next(p for p in pages if p["type"] == "page")["webSocketDebuggerUrl"]
        self._ws = wsc.connect(ws, max_size=200_000_000, open_timeout=timeout)
        self._ids = itertools.count(1)
        self._call("Page.enable")
        self._call("Emulation.setDeviceMetricsOverride",
                   {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})

    def _call(self, method: str, params: dict | None = None, *, timeout: float = 20.0) -> dict:
        i = next(self._ids)
        self._ws.send(json.dumps({"id": i, "method": method, "params": params or {}}))
        deadline = time.monotonic() + timeout
        while True:
            msg = json.loads(self._ws.recv(timeout=max(deadline - time.monotonic(), 0.01)))
            if msg.get("id") == i:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def open(self, url: str) -> None:
        self._call("Page.navigate", {"url": url})

    def screenshot(self) -> np.ndarray:
        """The page as an (H, W, 3) uint8 array."""
        from PIL import Image

        self._call("Runtime.evaluate", {"expression": _HIDE_NOTICES})
        data = self._call("Page.captureScreenshot", {"format": "png"})["data"]
        with Image.open(io.BytesIO(base64.b64decode(data))) as im:
            return np.asarray(im.convert("RGB"))

    def render(self, viewer, *, timeout: float = 60.0) -> np.ndarray:
        """The 3-D view (no control panel) as the browser renders it now, (H, W, 3) uint8.

        The render is requested through the viewer's websocket after everything sent
        before it, so it shows the state of the last `Viewer.sync` (viser's guarantee for
        scene state; mesh files decode asynchronously: see `settled`)."""
        assert viewer.sync(timeout)
        client = next(iter(viewer.server.get_clients().values()))
        rgba = client.get_render(height=min(self.height, 460), width=min(self.width, 700),
                                 transport_format="png", timeout=timeout).astype(float)
        alpha = rgba[..., 3:4] / 255.0
        return (rgba[..., :3] * alpha + 255.0 * (1.0 - alpha)).round().astype(np.uint8)

    def settled(self, viewer, *, timeout: float = 60.0) -> np.ndarray:
        """`render` repeated until two renders 0.3 s apart are equal (meshes decoded)."""
        deadline = time.monotonic() + timeout
        last = self.render(viewer, timeout=timeout)
        while time.monotonic() < deadline:
            time.sleep(0.3)
            shot = self.render(viewer, timeout=timeout)
            if np.array_equal(shot, last):
                return shot
            last = shot
        return last

    def close(self) -> None:
        try:
            if getattr(self, "_ws", None) is not None:
                self._ws.close()
        finally:
            if self._proc.poll() is None:
                self._proc.terminate()
                try:
                    self._proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self._proc.kill()
                    self._proc.wait(timeout=10)
            shutil.rmtree(self._dir, ignore_errors=True)


def wait_for_client(viewer, timeout: float = 60.0) -> bool:
    """Wait until a browser is connected to the viewer and its camera has reached the
    viewer's initial camera pose (it starts elsewhere and moves there)."""
    want = np.asarray(viewer.server.initial_camera.position, dtype=float)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        clients = list(viewer.server.get_clients().values())
        if clients:
            try:
                pos = np.asarray(clients[0].camera.position, dtype=float)
            except Exception:  # noqa: BLE001 - no camera message received yet
                pos = None
            if pos is not None and np.allclose(pos, want, atol=1e-3 * max(1.0, np.abs(want).max())):
                time.sleep(0.2)
                return True
        time.sleep(0.05)
    return False


def save_png(image: np.ndarray, path: Path) -> None:
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).save(path, optimize=True)
