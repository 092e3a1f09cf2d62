"""End to end: `wbcbench view` on a run, opened in headless Chromium (Debian's `chromium`, driven by Playwright
through its `executable_path`; nothing is downloaded). The timeline is moved in the page and screenshots of the
3-D view are compared: the robot is there (hiding it with its toggle changes the image), and the image at the
end of the walk differs from the one at its start.

Skipped, with the reason, when Playwright or a Chromium executable is missing (`.ci/run` installs Debian's
`chromium`)."""

import io
import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

playwright = pytest.importorskip("playwright.sync_api", reason="the Python package playwright is not installed "
                                                               "(pip install -e '.[test]')")

CHROMIUM = next((p for p in (os.environ.get("WBCBENCH_CHROMIUM"), "/usr/bin/chromium", shutil.which("chromium"),
                             shutil.which("chromium-browser")) if p and os.path.isfile(p)), None)
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="no Chromium executable (/usr/bin/chromium, or "
                                                         "WBCBENCH_CHROMIUM): apt-get install chromium")
WIDTH, HEIGHT = 800, 500
#: the 3-D view left of the GUI panel (which sits on the right), without the bottom-left axes gizmo
REGION = (slice(0, HEIGHT - 70), slice(0, int(0.55 * WIDTH)))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture()
def served(walk_run):
    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "wbcbench.cli", "view", str(walk_run), "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:  # serving once the port answers
            if proc.poll() is not None:
                pytest.fail(f"wbcbench view exited: {proc.stderr.read()}")
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{port}", timeout=5).close()  # the page is served
                break
            except OSError:
                time.sleep(0.3)
        else:
            pytest.fail("wbcbench view did not serve within 120 s")
        yield f"http://127.0.0.1:{port}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, proc.stderr.read()  # SIGTERM is a clean stop


def _shot(page) -> np.ndarray:
    from PIL import Image

    img = Image.open(io.BytesIO(page.screenshot(timeout=120_000))).convert("RGB")
    return np.asarray(img, dtype=int)[REGION]


def _changed(a: np.ndarray, b: np.ndarray) -> float:
    """Fraction of the region's pixels that differ by more than 30 in a colour channel."""
    return float((np.abs(a - b).max(axis=2) > 30).mean())


def test_replay_in_headless_chromium(served):
    with playwright.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True,
                                     args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
        try:
            page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            page.set_default_timeout(120_000)
            page.goto(served)
            slider = page.locator("[role=slider]")
            slider.wait_for()
            page.wait_for_timeout(1500)
            for close in page.locator(".mantine-Notification-closeButton").all():  # "software WebGL" notice
                close.click()
            page.wait_for_timeout(500)
            start = _shot(page)
            slider.press("End")  # the timeline to the end of the run (3 s: the right foot lifted and forward)
            page.wait_for_function("() => document.querySelector('[role=slider]')"
                                   ".getAttribute('aria-valuenow') === '3'")
            page.wait_for_timeout(1500)
            end = _shot(page)
            page.get_by_text("robots", exact=True).locator("xpath=following::input[@type='checkbox'][1]").click()
            page.wait_for_timeout(1500)
            no_robot = _shot(page)
        finally:
            browser.close()
    robot = _changed(end, no_robot)
    moved = _changed(start, end)
    assert robot > 0.015, f"the robot covers {robot:.1%} of the 3-D view"  # 3.7 % when written
    assert moved > 0.01, f"{moved:.2%} of the 3-D view changed from t = 0 to t = 3 s"  # 3.2 % when written
