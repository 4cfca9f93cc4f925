"""What the dashboard's tests share: node processes, a headless Chromium driven by Playwright, and
reading a page's pixels.

The browser is Debian's Chromium (``/usr/bin/chromium``; ``.ci/run`` installs it when missing),
launched by Playwright with an empty user-data directory and everything that would reach the
network off, so a page can load only what the dashboard serves.
"""

from __future__ import annotations

import io
import os
import re
import tempfile
from contextlib import contextmanager

import orjson
import pytest

import helpers
from helpers import wait_for

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
URL_RE = re.compile(r"hydromon dashboard: (http://127\.0\.0\.1:\d+/)")


class Procs(helpers.Procs):
    """Node processes (``helpers.Procs``), and the dashboard's URL once it serves."""

    def dashboard(self, name: str, *args: str, timeout_s: float = 60) -> str:
        """Start ``hydromon dashboard --port 0 ARGS``; its URL once it serves."""
        self.start(name, "dashboard", "--port", "0", *args)
        wait_for(lambda: URL_RE.search(self.log(name)), timeout_s, f"the {name}'s URL", alive=self.check_alive)
        return URL_RE.search(self.log(name)).group(1)


@contextmanager
def chromium():
    """A Playwright browser context of headless Chromium on an empty profile."""
    if not os.path.exists(CHROMIUM):
        pytest.fail(f"{CHROMIUM} is missing: apt-get install -y chromium (.ci/run does it)")
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="hydromon-chromium-") as profile, sync_playwright() as pw:
        ctx = pw.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, args=CHROMIUM_ARGS,
                                                    headless=True, viewport={"width": 1400, "height": 1000})
        try:
            yield ctx
        finally:
            ctx.close()


class Watched:
    """A page with its console errors, uncaught exceptions and dialogs collected."""

    def __init__(self, ctx):
        self.page = ctx.new_page()
        self.errors: list[str] = []
        self.dialogs: list[str] = []
        self.page.on("console", lambda m: self.errors.append(f"console: {m.text}") if m.type == "error" else None)
        self.page.on("pageerror", lambda e: self.errors.append(f"page error: {e}"))

        def on_dialog(d):
            self.dialogs.append(d.message)
            d.dismiss()

        self.page.on("dialog", on_dialog)


def fleet_grades(page) -> dict[str, str]:
    """Rig -> the grade the fleet page shows."""
    return page.evaluate("""() => Object.fromEntries([...document.querySelectorAll('#fleet tbody tr')]
        .map(tr => [tr.dataset.rig, tr.querySelector('td.grade').textContent]))""")


def fleet_flags(page) -> dict[str, str]:
    """Rig -> its flag on the fleet page ('' when none)."""
    return page.evaluate("""() => Object.fromEntries([...document.querySelectorAll('#fleet tbody tr')]
        .map(tr => [tr.dataset.rig, (tr.querySelector('.flag') || {textContent: ''}).textContent]))""")


def ink(png: bytes, background=(255, 255, 255)) -> tuple[int, int]:
    """``(pixels not of the background colour, distinct colours)`` of a PNG screenshot."""
    from PIL import Image

    img = Image.open(io.BytesIO(png)).convert("RGB")
    colours = img.getcolors(maxcolors=1 << 20) or []
    other = sum(n for n, c in colours if c != background)
    return other, len(colours)


def dumps(obj) -> bytes:
    return orjson.dumps(obj)
