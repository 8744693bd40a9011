"""The Rerun web viewer the bridge serves, opened in a real browser: `viewer-bridge run -c
builtin:rerun --demo` with `rerun.serve` on free ports, Debian's headless Chromium driven over its
DevTools protocol (JSON over a WebSocket), a screenshot once the demo scene is drawn.

The 3D view is "not empty" when the middle of the page holds pixels of colours the viewer's own
background and chrome never use: the demo's shapes are saturated colours. WebGL runs on
SwiftShader (software), so no GPU is needed.
"""

from __future__ import annotations

import base64
import io
import json
import shutil
import subprocess
import tempfile
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from websockets.sync.client import connect

from tests.conftest import lcm_url
from tests.peers import BridgeProcess

pytestmark = pytest.mark.e2e  # starts peers or bridges (`./dev test --stress N` repeats it)

DOCS_SCREENSHOT = Path(__file__).parents[2] / "docs" / "rerun_web_viewer.png"
CHROMIUM_FLAGS = [
    "--headless=new",
    "--no-sandbox",  # root in CI containers
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",  # WebGL on the CPU
    "--window-size=1280,800",
    "--remote-debugging-port=0",
    "--no-first-run",
]


@pytest.fixture
def web_bridge() -> Iterator[str]:
    """A bridge serving the web viewer with the demo scene; yields the URL its start-up line prints."""
    bridge = BridgeProcess(
        "-c", "builtin:rerun", "--demo", "--lcm-url", lcm_url(31),
        "--set", "rerun.connect=", "--set", "rerun.serve=true",
        "--set", "rerun.grpc_port=0", "--set", "rerun.web_port=0",
    )  # fmt: skip
    try:
        line = bridge.wait_for_line("web viewer http://")
        yield line.split("web viewer ", 1)[1].split()[0]
    finally:
        bridge.stop()


def _page_socket(folder: Path, deadline: float) -> str:
    """The DevTools WebSocket of Chromium's one page (the port is in DevToolsActivePort)."""
    port_file = folder / "DevToolsActivePort"
    while time.monotonic() < deadline:
        if port_file.exists() and port_file.read_text().strip():
            port = port_file.read_text().split()[0]
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as answer:
                pages = [target for target in json.load(answer) if target["type"] == "page"]
            if pages:
                return str(pages[0]["webSocketDebuggerUrl"])
        time.sleep(0.2)
    raise AssertionError("Chromium never opened its DevTools port")


def _screenshot(socket_url: str) -> Image.Image:
    with connect(socket_url, max_size=None, open_timeout=30) as page:
        page.send(json.dumps({"id": 1, "method": "Page.captureScreenshot", "params": {"format": "png"}}))
        while True:
            answer = json.loads(page.recv(timeout=60))
            if answer.get("id") == 1:
                return Image.open(io.BytesIO(base64.b64decode(answer["result"]["data"]))).convert("RGB")


def _scene_pixels(shot: Image.Image) -> int:
    """Pixels in the middle of the page that are strongly coloured (the viewer's UI is grey)."""
    pixels = np.asarray(shot, dtype=np.int16)
    height, width, _ = pixels.shape
    middle = pixels[height // 6 : height * 5 // 6, width // 6 : width * 5 // 6]
    saturation = middle.max(axis=2) - middle.min(axis=2)
    return int((saturation > 60).sum())


def test_web_viewer_shows_the_scene(web_bridge: str) -> None:
    chromium = shutil.which("chromium")
    assert chromium, "./dev test installs Debian's chromium"
    with tempfile.TemporaryDirectory() as folder:
        browser = subprocess.Popen(
            [chromium, *CHROMIUM_FLAGS, f"--user-data-dir={folder}", web_bridge],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            deadline = time.monotonic() + 120  # the viewer's Wasm compiles on a loaded CPU
            socket_url = _page_socket(Path(folder), deadline)
            shot = _screenshot(socket_url)
            while _scene_pixels(shot) < 500 and time.monotonic() < deadline:
                time.sleep(1.0)
                shot = _screenshot(socket_url)
            time.sleep(2.0)  # let the view settle for the picture in docs/
            shot = _screenshot(socket_url)
        finally:
            browser.terminate()
            browser.wait(timeout=30)
    shot.save(Path(folder).parent / "rerun_web_viewer_last.png")
    assert _scene_pixels(shot) >= 500, "the 3D view stayed empty"
    if not DOCS_SCREENSHOT.exists():
        shot.save(DOCS_SCREENSHOT)
