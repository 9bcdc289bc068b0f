"""The viewer in a real browser: Debian's headless Chromium, driven by Playwright (``executable_path``),
loads ``smplcore view`` from a local port and must show a body; moving widgets through the Python API
must change the mesh on the server and the picture in the browser.

Skipped, with the reason, only where Chromium is not installed (``.ci/run`` installs it) or Playwright
is missing (it is in the ``test`` extra).
"""

from __future__ import annotations

import io
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser", reason="the viewer needs viser: pip install 'smplcore[view]'")

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
VIEWPORT = {"width": 800, "height": 500}
# Software WebGL (SwiftShader) in a headless browser running as root.
CHROMIUM_ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-gpu-sandbox"]


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def browser():
    if CHROMIUM is None:
        pytest.skip("Chromium is not installed (Debian: apt-get install chromium; .ci/run installs it)")
    sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright is missing: pip install playwright")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


def screenshot(page) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(page.screenshot(timeout=120_000))).convert("RGB")).astype(int)


def centre(img: np.ndarray) -> np.ndarray:
    """The middle of the canvas left of the GUI panel (right), below notifications (top left)."""
    h, w = img.shape[:2]
    return img[int(0.3 * h) : int(0.9 * h), int(0.2 * w) : int(0.57 * w)]


def body_fraction(img: np.ndarray) -> float:
    """Share of the centre's pixels in the bodies' warm colour (the background is white, the floor grey)."""
    c = centre(img)
    warm = (c[..., 0] > 90) & (c[..., 0] - c[..., 2] > 35)
    return float(warm.mean())


def wait_for(page, condition, timeout: float = 60.0) -> np.ndarray:
    """Screenshots until ``condition(image)`` holds; returns the last one (the caller asserts on it)."""
    deadline = time.time() + timeout
    img = screenshot(page)
    while not condition(img) and time.time() < deadline:
        page.wait_for_timeout(500)
        img = screenshot(page)
    return img


def test_smplcore_view_shows_a_body_in_chromium(browser, tmp_path):
    port = free_port()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).parents[1] / "src"), *sys.path]))
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "smplcore.cli",
            "view",
            "--port",
            str(port),
            "--out-dir",
            str(tmp_path),
            "--lighting",
            "simple",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    try:
        line = proc.stdout.readline()
        assert f"127.0.0.1:{port}" in line, (
            f"smplcore view did not start: {line}{proc.stdout.read() if proc.poll() else ''}"
        )
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(line.split(" at ", 1)[1].strip())  # the printed address, with the session token
        img = wait_for(page, lambda im: body_fraction(im) > 0.02)
        from PIL import Image

        Image.fromarray(img.astype(np.uint8)).save(tmp_path / "view.png")
        assert body_fraction(img) > 0.02, f"no body in the screenshot {tmp_path / 'view.png'}"
        page.close()
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0


def test_widgets_change_the_mesh_and_the_picture(browser, tmp_path):
    from smplcore.view import show

    viewer = show(port=free_port(), out_dir=tmp_path, lighting="simple")
    try:
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(viewer.url)
        before = wait_for(page, lambda im: body_fraction(im) > 0.02)
        assert body_fraction(before) > 0.02
        mesh = viewer._nodes[0]["mesh"]
        verts_before = np.array(mesh.vertices)

        c = viewer.controls
        c.joint.value = "left_shoulder"
        c.rotation[2].value = -75.0  # the left arm comes down from the T-pose
        c.joint.value = "right_shoulder"
        c.rotation[2].value = 75.0
        c.betas[0].value = 2.5
        verts_after = np.array(mesh.vertices)
        assert np.abs(verts_after - verts_before).max() > 0.3  # a hand moved by more than 30 cm (server side)

        def changed(im: np.ndarray) -> bool:
            return float(np.abs(centre(im) - centre(before)).mean()) > 1.0

        after = wait_for(page, changed)
        assert changed(after), "the browser still shows the old pose"
        assert body_fraction(after) > 0.02

        mesh.visible = False  # an empty scene: no body colour left
        empty = wait_for(page, lambda im: body_fraction(im) < 0.001)
        assert body_fraction(empty) < 0.001 < body_fraction(after)
        page.close()
    finally:
        viewer.close()
