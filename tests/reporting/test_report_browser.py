"""The run report as a reader sees it, in a real headless browser (Debian's chromium).

The test injects a small script into a copy of the report that, once the page and all its
images have loaded, writes what a reader would check into the DOM (sections present,
images decoded with a non-zero natural width, horizontal overflow of the page and of every
table at a 1400 px wide window); ``chromium --dump-dom`` prints that DOM. This needs no
driver, no extra Python package and no open port: one browser process, a few seconds.
Skipped when chromium is absent, except on CI (``CI=true``), where it must be installed.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import pytest

from workbench.dashboard.browser import HEADLESS_FLAGS, find_chromium
from workbench.reporting.report import build_report

WIDTH = 1400

_CHECKS = """
<script>
window.addEventListener("load", () => {
  const images = [...document.images].map(img => ({
    src: img.getAttribute("src"), complete: img.complete, width: img.naturalWidth,
    right: img.getBoundingClientRect().right}));
  const tables = [...document.querySelectorAll("table")].map(t => ({
    caption: (t.caption || {}).textContent || "", right: t.getBoundingClientRect().right}));
  const out = {
    viewport: window.innerWidth,
    scrollWidth: document.documentElement.scrollWidth,
    sections: [...document.querySelectorAll("section")].map(s => ({
      id: s.id, title: (s.querySelector("h2") || {}).textContent})),
    images: images, tables: tables,
    text: document.body.innerText,
  };
  const pre = document.createElement("pre");
  pre.id = "reader-checks";
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
});
</script>
"""


@pytest.fixture(scope="module")
def browser():
    path = find_chromium()
    if path is None:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail("chromium is not installed; CI must install it (see .ci/run)")
        pytest.skip("chromium not installed (apt-get install chromium)")
    return path


def _read_page(browser: str, page: Path, profile: Path) -> dict:
    """What a reader sees on *page*, measured by the injected script in chromium."""
    probe = page.with_name("_reader_checks.html")
    probe.write_text(
        page.read_text(encoding="utf-8").replace("</body>", _CHECKS + "</body>"), encoding="utf-8"
    )
    command = [
        browser,
        *HEADLESS_FLAGS,
        f"--user-data-dir={profile}",
        f"--window-size={WIDTH},900",
        "--virtual-time-budget=15000",
        "--dump-dom",
        probe.resolve().as_uri(),
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=90)
    match = re.search(r'<pre id="reader-checks">(.*?)</pre>', done.stdout, re.S)
    assert match, f"no checks in the DOM; chromium said: {done.stderr[-2000:]}"
    import html

    return json.loads(html.unescape(match.group(1)))


@pytest.fixture(scope="module")
def seen(short_run, browser, tmp_path_factory):
    page = build_report(short_run, dpi=80)
    return _read_page(browser, page, tmp_path_factory.mktemp("profile"))


def test_sections_in_reading_order(seen):
    ids = [s["id"] for s in seen["sections"]]
    assert ids[0] == "overview"
    for wanted in ("signals", "identification", "modes", "correlation", "regression", "forecast"):
        assert wanted in ids, wanted
    assert ids.index("identification") < ids.index("modes") < ids.index("forecast")


def test_every_figure_loaded(seen):
    images = seen["images"]
    assert len(images) >= 10
    broken = [i["src"] for i in images if not i["complete"] or i["width"] == 0]
    assert not broken, broken
    sources = " ".join(i["src"] for i in images)
    for view in ("tracked_modes", "automac", "mode_shapes", "spectra", "moments",
                 "stabilisation_block", "correlation_heatmap", "forecast_A", "observed_vs_predicted"):  # fmt: skip
        assert view in sources, view


def test_no_horizontal_overflow_at_1400_px(seen):
    assert seen["viewport"] == WIDTH
    assert seen["scrollWidth"] <= WIDTH
    assert all(t["right"] <= WIDTH for t in seen["tables"]), seen["tables"]
    assert all(i["right"] <= WIDTH for i in seen["images"])


def test_reader_sees_units_and_no_internals(seen):
    text = seen["text"]
    assert "damping [%]" in text and "frequency [Hz]" in text
    assert "Warnings" in text and "Modes found" in text
    assert "store/" not in text and ".npz" not in text and "day=" not in text
