"""The dashboard as a reader sees it, in a real headless browser (Debian's chromium).

One chromium per module, driven over the DevTools protocol by
:mod:`workbench.dashboard.browser` (standard library only): the page is loaded once from
a dashboard server in this process, what it shows is read from the DOM, and blocks are
then published into the state folder while the page stays open, to see them appear
without a reload. Skipped when chromium is absent, except on CI (``CI=true``).
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pandas as pd
import pytest

from workbench.dashboard import DashboardOptions
from workbench.dashboard.browser import HeadlessChromium, find_chromium

from .conftest import publish

#: What a reader sees, gathered in the page.
READ_PAGE = """(() => {
  const text = (sel) => [...document.querySelectorAll(sel)].map((n) => n.innerText.trim());
  const visible = (sel) => { const n = document.querySelector(sel);
                             return !!n && n.getClientRects().length > 0; };
  const panels = [...document.querySelectorAll("#mode-panels .mode-panel")];
  const ssi = (p) => p.querySelector(`g.series[data-key="${p.dataset.mode}"]`);
  return {
    status: document.getElementById("status").innerText,
    cards: [...document.querySelectorAll("#modes .mode-card")].map((c) => ({
      mode: +c.dataset.mode, text: c.innerText, stale: c.classList.contains("stale")})),
    modesHeading: document.querySelector("#modes h2").innerText,
    series: panels.filter(ssi).map((p) => ({key: +p.dataset.mode, points: +ssi(p).dataset.points,
                                circles: ssi(p).querySelectorAll("circle").length,
                                colour: ssi(p).querySelector("path").getAttribute("stroke")})),
    legend: text("#tracked .legend span"),
    healthHeading: document.querySelector("#health h2").innerText,
    healthLimit: document.querySelectorAll("#health-chart path.limit").length,
    healthLine: document.querySelectorAll("#health-chart path.statistic").length,
    alarmPoints: document.querySelectorAll("#health-chart circle.alarm-point").length,
    alarmRows: text("#alarms tbody tr"),
    activeAlarms: document.querySelectorAll("#alarms tr.active").length,
    facts: Object.fromEntries([...document.querySelectorAll("#data_health dd")].map(
      (d) => [d.dataset.fact, d.innerText])),
    healthRows: document.querySelectorAll("#data_health tbody tr").length,
    placeholders: ["modes", "tracked", "health", "alarms", "data_health"].filter(
      (id) => visible(`#${id} .placeholder`)),
    polls: window.dashboard.polls,
    errors: window.dashboard.errors ? window.dashboard.lastError : null,
    marker: window.__notReloaded || null,
    scrollWidth: document.documentElement.scrollWidth,
  };
})()"""


@pytest.fixture(scope="module")
def browser():
    if find_chromium() is None:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail("chromium is not installed; CI must install it (see .ci/run)")
        pytest.skip("chromium not installed (apt-get install chromium)")
    with HeadlessChromium(width=1400, height=1000) as chromium:
        yield chromium


def _shows(page, panel: str, block: int) -> None:
    page.wait_for(f"document.getElementById('{panel}').dataset.block === '{block}'", timeout=15)


def _settled(page) -> None:
    """Wait for the poll in flight (and its panel fetches) to finish."""
    polls = page.evaluate("window.dashboard.polls")
    page.wait_for(f"window.dashboard.polls > {polls}", timeout=15)


def test_reader_sees_modes_series_health_alarms_and_data_health(browser, voyage, tmp_path, serve):
    onset = int(voyage.alarms["start_block"].iloc[0])
    newest = onset + 6
    state = publish(voyage, tmp_path, newest)
    served = serve(tmp_path, DashboardOptions(hours=6.0, health_hours=24.0, poll_seconds=0.2))
    page = browser.open(served.url)
    for panel in ("modes", "tracked", "health", "data_health", "status"):
        _shows(page, panel, newest)
    _settled(page)
    seen = page.evaluate(READ_PAGE)

    # status line
    assert f"last block {newest}" in seen["status"] and "monitor running" in seen["status"]
    # one card per mode, newest frequency and the forecast's bounds as printed numbers
    forecast = state.forecast[state.forecast["block"] == newest].set_index("mode")
    tracked = state.tracked[state.tracked["block"] == newest].set_index("mode")
    assert [c["mode"] for c in seen["cards"]] == sorted(state.tracked["mode"].unique())
    for card in seen["cards"]:
        row = forecast.loc[card["mode"]]
        assert card["text"].startswith(f"Mode {card['mode']}")
        bounds = f"[{row['model_lower_hz']:.3f}, {row['model_upper_hz']:.3f}] Hz"
        assert f"model {row['model_frequency_hz']:.3f} {bounds}" in card["text"]
        kalman = f"Kalman {row['kalman_frequency_hz']:.3f} ± {1.96 * row['kalman_std_hz']:.3f} Hz"
        assert f"{kalman} (95 %)" in card["text"]
        if card["mode"] in tracked.index:
            assert f"{tracked.loc[card['mode'], 'frequency_hz']:.3f} Hz" in card["text"]
            assert not card["stale"]
        else:
            assert card["stale"] and f"not identified in block {newest}" in card["text"]
    # tracked frequencies: one coloured series per mode, every block of the last 6 h
    window = state.tracked[state.tracked["block"].between(newest - 71, newest)]
    counts = window.groupby("mode").size()
    assert [s["key"] for s in seen["series"]] == counts.index.tolist()
    assert [s["points"] for s in seen["series"]] == counts.tolist()
    assert [s["circles"] for s in seen["series"]] == counts.tolist()
    assert len({s["colour"] for s in seen["series"]}) == len(counts)
    assert seen["legend"] == [
        "tracked (SSI)",
        "model",
        "model 95 % band",
        "shaft order (not a mode)",
    ]
    # health chart: the statistic, its limit, the alarming blocks
    health = state.health[state.health["block"] <= newest]
    assert seen["healthLine"] == 1 and seen["healthLimit"] == 1
    assert seen["alarmPoints"] == int(health["alarm"].sum()) > 0
    assert f"limit {health['limit'].iloc[-1]:.2f}" in seen["healthHeading"]
    shares = health.iloc[-1][[f"contribution_{m}" for m in range(1, 8)]].astype(float)
    top = shares[shares >= 0.05].sort_values(ascending=False).iloc[:3]
    driven = ", ".join(f"mode {c[13:]} {math.floor(100 * v + 0.5)} %" for c, v in top.items())
    assert seen["healthHeading"].endswith(f"· ALARM · driven by {driven}")
    # alarm list: the ongoing episode, naming the damaged mode
    assert len(seen["alarmRows"]) == 1 and seen["activeAlarms"] == 1
    assert "ongoing" in seen["alarmRows"][0] and "mode 3" in seen["alarmRows"][0]
    # data health of the newest block
    latest = state.data_health.set_index("block").loc[newest]
    assert seen["facts"]["channels"] == str(latest["n_channels"])
    assert seen["facts"]["dropped now"] == (latest["dropped_channels"] or "none")
    assert seen["facts"]["latency"].startswith(f"{latest['latency_s']:.1f} s (median ")
    assert seen["healthRows"] == 12
    assert seen["placeholders"] == []
    assert seen["scrollWidth"] <= 1400

    # live: publish three more blocks, one at a time, and watch each appear, no reload
    page.evaluate("window.__notReloaded = 'yes'")
    polls = seen["polls"]
    for _ in range(3):
        block = state.append()
        for panel in ("modes", "tracked", "health", "alarms", "data_health"):
            page.wait_for(f"document.getElementById('{panel}').dataset.block !== ''")
        _shows(page, "modes", block)
        _shows(page, "tracked", block)
        _shows(page, "health", block)
        _shows(page, "data_health", block)
        _shows(page, "status", block)  # written last
    _settled(page)
    after = page.evaluate(READ_PAGE)
    assert after["marker"] == "yes" and after["polls"] > polls
    assert seen["errors"] is None and after["errors"] is None
    assert f"last block {newest + 3}" in after["status"]
    grown = state.tracked[state.tracked["block"].between(newest + 3 - 71, newest + 3)]
    assert sum(s["points"] for s in after["series"]) == len(grown)
    assert "ongoing" in after["alarmRows"][0]


def test_waiting_then_filling_without_reload(browser, voyage, tmp_path, serve):
    served = serve(tmp_path, DashboardOptions(poll_seconds=0.2))
    page = browser.open(served.url)
    page.wait_for("window.dashboard && window.dashboard.polls > 1")
    seen = page.evaluate(READ_PAGE)
    assert seen["placeholders"] == ["modes", "tracked", "health", "alarms", "data_health"]
    assert "waiting for data" in seen["status"]
    assert seen["cards"] == [] and seen["series"] == []
    page.evaluate("window.__notReloaded = 'yes'")

    # the monitor's first blocks: modes and data health fill, health still learns
    state = publish(voyage, tmp_path, 30)
    _shows(page, "modes", 30)
    _shows(page, "data_health", 30)
    _shows(page, "status", 30)
    _settled(page)
    seen = page.evaluate(READ_PAGE)
    assert seen["placeholders"] == ["health", "alarms"]
    assert len(seen["cards"]) == 7 and len(seen["series"]) == 7

    # a torn write of a table: the page keeps the last good data and says why
    (tmp_path / "tracked.parquet").write_bytes(b"PAR1 torn")
    page.wait_for("!!document.querySelector('#tracked .note')")
    assert "tracked.parquet" in page.evaluate("document.querySelector('#tracked .note').innerText")
    assert len(page.evaluate(READ_PAGE)["series"]) == 7

    # the reference period completes: the health chart and the (empty) alarm list appear
    state.write(voyage.reference_end_block)
    _shows(page, "health", voyage.reference_end_block)
    page.wait_for("document.getElementById('alarms').dataset.block === '0'")
    _shows(page, "status", voyage.reference_end_block)
    _settled(page)
    seen = page.evaluate(READ_PAGE)
    assert seen["placeholders"] == [] and seen["alarmRows"] == []
    assert "learning reference" in seen["healthHeading"] or "in control" in seen["healthHeading"]
    assert page.evaluate("!!document.querySelector('#tracked .note')") is False
    assert seen["marker"] == "yes" and seen["errors"] is None


def test_a_silent_monitor_is_flagged(browser, voyage, tmp_path, serve):
    publish(voyage, tmp_path, 100)
    status_file = tmp_path / "status.json"
    status = json.loads(status_file.read_text())
    hour_ago = pd.Timestamp.now(tz="UTC") - pd.Timedelta(minutes=61)
    status["updated_at"] = hour_ago.strftime("%Y-%m-%dT%H:%M:%SZ")
    status_file.write_text(json.dumps(status))
    page = browser.open(serve(tmp_path, DashboardOptions(poll_seconds=0.2)).url)
    text = page.wait_for("document.getElementById('status-stale').innerText")
    assert text == "no news from the monitor for 61 min"
    # a monitor that says it stopped is not silent: it says so
    status_file.write_text(json.dumps({**status, "state": "stopped", "message": "disk full"}))
    page.wait_for("document.getElementById('status-state').innerText === 'monitor stopped'")
    _settled(page)
    assert page.evaluate("document.getElementById('status-stale').innerText") == ""
    assert "disk full" in page.evaluate("document.getElementById('status').innerText")


#: Installed before the page's own scripts: every Content-Security-Policy violation.
WATCH_CSP = """window.__csp = [];
document.addEventListener("securitypolicyviolation",
  (e) => window.__csp.push(`${e.effectiveDirective} ${e.blockedURI}`));"""


def test_page_renders_under_its_content_security_policy(browser, voyage, tmp_path, serve):
    """The strict policy (no inline script or style) blocks nothing the page needs: every
    panel shows its data, with no violation; an injected inline script or style is
    refused (so the watcher would see a violation of the page's own)."""
    newest = int(voyage.alarms["start_block"].iloc[0]) + 6  # every panel has data
    publish(voyage, tmp_path, newest)
    served = serve(tmp_path, DashboardOptions(poll_seconds=0.2))
    page = browser.open("about:blank")
    page.call("Page.enable")
    page.call("Page.addScriptToEvaluateOnNewDocument", source=WATCH_CSP)
    page.navigate(served.url)
    for panel in ("modes", "tracked", "health", "data_health", "status"):
        _shows(page, panel, newest)
    _settled(page)
    seen = page.evaluate(READ_PAGE)
    assert len(seen["cards"]) == 7 and len(seen["series"]) == 7
    assert seen["healthLine"] == 1 and seen["healthRows"] == 12
    assert seen["placeholders"] == [] and seen["errors"] is None
    # the mode colours are set through the CSSOM (allowed), not inline style attributes
    colours = page.evaluate(
        "[...document.querySelectorAll('.mode-card')].map("
        "(c) => getComputedStyle(c).getPropertyValue('--mode').trim())"
    )
    assert len(set(colours)) == 7 and all(colours)
    assert page.evaluate("window.__csp") == []
    page.evaluate(
        "(() => { const s = document.createElement('script');"
        " s.textContent = 'window.__injected = 1'; document.body.append(s);"
        " document.body.setAttribute('style', 'color: red'); })()"
    )
    page.wait_for("window.__csp.length >= 2")
    violations = page.evaluate("window.__csp")
    assert page.evaluate("window.__injected === undefined")
    assert {v.split()[0] for v in violations} == {"script-src-elem", "style-src-attr"}


def test_given_up_blocks_are_named_on_the_page(browser, voyage, tmp_path, serve):
    """The blocks the monitor gave up (a file after its late window) appear in the status
    line with their span, and go away when the status has none."""
    publish(voyage, tmp_path, 100)
    status_file = tmp_path / "status.json"
    status = json.loads(status_file.read_text())
    spans = [
        {"first_block": 40, "last_block": 43, "start": "2026-03-01T03:20:00Z",
         "end": "2026-03-01T03:55:00Z", "reason": "gap of 300.0 s between a.npz and b.npz"},
        {"first_block": 60, "last_block": 60, "start": "2026-03-01T05:00:00Z",
         "end": "2026-03-01T05:20:00Z", "reason": "no data (gap between c.npz and d.npz)"},
    ]  # fmt: skip
    note = "5 block(s) given up, ...: `workbench identify /data --out DIR` includes them"
    status_file.write_text(json.dumps({**status, "given_up": spans, "given_up_note": note}))
    page = browser.open(serve(tmp_path, DashboardOptions(poll_seconds=0.2)).url)
    text = page.wait_for("document.getElementById('status-given-up').innerText")
    assert text == (
        "blocks given up: 40-43 (2026-03-01 03:20 to 2026-03-01 03:55 UTC), "
        "60 (2026-03-01 05:00 to 2026-03-01 05:20 UTC) - workbench identify over the folder "
        "includes them"
    )
    assert page.evaluate("document.getElementById('status-given-up').title") == note
    status_file.write_text(json.dumps({**status, "message": "resumed"}))
    page.wait_for("document.getElementById('status').innerText.includes('resumed')")
    assert page.evaluate("document.getElementById('status-given-up').innerText") == ""


#: Per mode panel: its heading, the y-axis (tick values and positions), the newest SSI
#: point and the model band's outline, in the SVG's own coordinates.
READ_MODE_PANELS = """(() => [...document.querySelectorAll("#mode-panels .mode-panel")].map((p) => {
  const svg = p.querySelector("svg");
  const ticks = [...svg.querySelectorAll("g.axes text")].filter(
    (t) => t.getAttribute("text-anchor") === "end" && !t.getAttribute("transform"));
  const ssi = svg.querySelector(`g.series[data-key="${p.dataset.mode}"]`);
  const circles = ssi ? [...ssi.querySelectorAll("circle")] : [];
  const last = circles[circles.length - 1];
  return {
    mode: +p.dataset.mode,
    heading: p.querySelector("h3").innerText,
    nowOutside: p.querySelector("h3 .now").classList.contains("outside"),
    ylabel: [...svg.querySelectorAll("g.axes text[transform]")].map((t) => t.textContent),
    ticks: ticks.map((t) => [+t.textContent, +t.getAttribute("y") - 4]),
    points: circles.length,
    last: last ? [+last.getAttribute("cx"), +last.getAttribute("cy")] : null,
    bands: [...svg.querySelectorAll("path.band")].map((b) => b.getAttribute("d")),
    model: svg.querySelectorAll("g.series[data-key=model] path.model").length,
    orders: [...svg.querySelectorAll("path.harmonic")].map((h) => ({
      label: h.parentNode.querySelector("text.series-label").textContent,
      circles: h.parentNode.querySelectorAll("circle").length,
      dash: getComputedStyle(h).strokeDasharray})),
  };
}))()"""


def _scale(ticks: list[list[float]]) -> tuple[float, float]:
    """(pixels per %, pixel of 0 %) from the y-axis tick labels (value, pixel)."""
    (v0, y0), (v1, y1) = ticks[0], ticks[-1]
    per = (y0 - y1) / (v1 - v0)
    return per, y0 + v0 * per


def _points(path: str) -> list[tuple[float, float]]:
    return [tuple(map(float, p.split(","))) for p in path.strip("MZ").split("L")]


def test_mode_panels_show_the_change_in_percent_with_the_model_band(
    browser, voyage, tmp_path, serve
):
    """Issue 29: one panel per mode, in % against the mode's reference (the median of its
    tracked frequency over the health chart's reference period), with the model's 95 %
    band; 0.5 % spans several pixels (on the former shared 2.8-8.3 Hz axis of 244 px it
    was 0.6 px for mode 1), the newest point sits at its relative change, and mode 3's
    stiffness loss reads as a drop out of its band."""
    onset = int(voyage.alarms["start_block"].iloc[0])
    newest = onset + 6
    state = publish(voyage, tmp_path, newest)
    served = serve(tmp_path, DashboardOptions(hours=6.0, poll_seconds=0.2))
    page = browser.open(served.url)
    _shows(page, "tracked", newest)
    _settled(page)
    panels = page.evaluate(READ_MODE_PANELS)
    sub = page.evaluate("document.getElementById('tracked-sub').innerText")
    reference_blocks = state.health.loc[state.health["phase"] == "reference", "block"]
    first, last = int(reference_blocks.min()), int(reference_blocks.max())
    assert f"reference: median over the health reference period (blocks {first}-{last})" in sub
    tracked = state.tracked[state.tracked["block"] <= newest]
    in_reference = tracked[tracked["block"].between(first, last)]
    references = in_reference.groupby("mode")["frequency_hz"].median()
    window = tracked[tracked["block"].between(newest - 71, newest)]
    forecast = state.forecast[state.forecast["block"].between(newest - 71, newest)]
    assert [p["mode"] for p in panels] == list(range(1, 8))
    for panel in panels:
        mode = panel["mode"]
        reference = references[mode]
        rows = window[window["mode"] == mode].sort_values("block")
        change = 100.0 * (rows["frequency_hz"].iloc[-1] / reference - 1.0)
        sign = "+" if change > 0 else "−"
        assert panel["heading"] == f"Mode {mode} {sign}{abs(change):.2f} % vs {reference:.3f} Hz"
        assert panel["ylabel"] == ["change [%]"] and panel["points"] == len(rows)
        per_percent, zero = _scale(panel["ticks"])
        # half a per cent is visible: 5 px at least here (the demo's daily temperature
        # swing widens some panels), 10x what the shared axis gave the lowest mode
        shared = 244.0 * 0.005 * references.min() / (1.1 * np.ptp(window["frequency_hz"]))
        assert per_percent * 0.5 > max(5.0, 10.0 * shared)
        # the newest point is drawn at its relative change (SVG coordinates to 0.1 px)
        assert (zero - panel["last"][1]) / per_percent == pytest.approx(change, abs=0.02)
        # the band: one outline over the 72 blocks, upper bounds then lower bounds
        band = forecast[forecast["mode"] == mode].sort_values("block")
        assert len(panel["bands"]) == 1 and panel["model"] == 1
        outline = _points(panel["bands"][0])
        assert len(outline) == 2 * len(band) == 144
        upper = 100.0 * (band["model_upper_hz"].iloc[-1] / reference - 1.0)
        lower = 100.0 * (band["model_lower_hz"].iloc[-1] / reference - 1.0)
        assert (zero - outline[len(band) - 1][1]) / per_percent == pytest.approx(upper, abs=0.02)
        assert (zero - outline[len(band)][1]) / per_percent == pytest.approx(lower, abs=0.02)
        assert panel["nowOutside"] == (not lower <= change <= upper)
        assert panel["orders"] == []  # no shaft speed logged: no order drawn
    # the 3 % stiffness loss of mode 3 (1.5 % in frequency): below its band, in amber
    mode3 = panels[2]
    assert mode3["heading"].startswith("Mode 3 −1.") and mode3["nowOutside"]
    # without a logged shaft speed the shaft panel says why it is empty
    assert page.evaluate("document.querySelector('#shaft .placeholder').innerText") == (
        "waiting for data: harmonics.parquet not written yet: the shaft orders are known "
        "only from a ship log with the shaft speed (shaft_rpm), or with the speed once a "
        "line follows it"
    )


def test_shaft_orders_and_harmonic_lines_are_shown_as_such_never_as_modes(
    browser, voyage, tmp_path, serve
):
    """The shaft orders at the logged shaft speed (174 rpm: order 1 at 2.9 Hz, 1.5 % above
    mode 1) and a tracked line that is order 1's harmonic: listed and drawn as shaft
    orders and harmonics, the order dashed and labelled in mode 1's panel only, no card
    or panel of their own."""
    from data_contracts import write_table
    from workbench.dashboard.state import HARMONIC_LINES, HARMONIC_TRACKS

    newest = 150
    state = publish(voyage, tmp_path, newest)
    blocks = state.tracked[["block", "block_start"]].drop_duplicates("block")
    blocks = blocks[blocks["block"] <= newest]
    rpm = 174.0
    lines = pd.concat(
        [blocks.assign(order=k, frequency_hz=k * rpm / 60.0) for k in (1.0, 2.0, 3.0, 5.0)],
        ignore_index=True,
    )
    write_table(lines, tmp_path / "harmonics.parquet", HARMONIC_LINES)
    track = blocks.iloc[::2].assign(track=1, frequency_hz=2.906, order=1.0)
    write_table(track, tmp_path / "harmonic_tracks.parquet", HARMONIC_TRACKS)
    served = serve(tmp_path, DashboardOptions(hours=6.0, poll_seconds=0.2))
    page = browser.open(served.url)
    for panel in ("tracked", "shaft", "modes"):
        _shows(page, panel, newest)
    _settled(page)
    panels = page.evaluate(READ_MODE_PANELS)
    seen = page.evaluate(READ_PAGE)
    shaft = page.evaluate(
        """(() => ({
      sub: document.getElementById("shaft-sub").innerText,
      orders: [...document.querySelectorAll("#shaft-orders dd")].map((d) => [
        d.previousElementSibling.innerText, d.innerText]),
      tracks: [...document.querySelectorAll("#shaft-tracks li")].map((l) => l.innerText),
      lines: [...document.querySelectorAll("#shaft-chart path.harmonic")].map((p) =>
        p.parentNode.querySelector("text.series-label").textContent),
      points: document.querySelectorAll("#shaft-chart circle.harmonic-point").length,
    }))()"""
    )
    # modes only among the cards and the mode panels
    assert [c["mode"] for c in seen["cards"]] == [p["mode"] for p in panels] == list(range(1, 8))
    # order 1 passes 1.5 % above mode 1 (reference 2.857 Hz): drawn dashed and named there
    near = [p["mode"] for p in panels if p["orders"]]
    assert near == [1]
    assert [o["label"] for o in panels[0]["orders"]] == ["order 1×"]
    assert panels[0]["orders"][0]["circles"] == 0
    assert panels[0]["orders"][0]["dash"] not in ("", "none")
    per_percent, zero = _scale(panels[0]["ticks"])
    assert per_percent > 0
    # the shaft panel: the orders' frequencies now, the harmonic line as such
    assert shaft["sub"] == f"block {newest} · shaft 174.0 rpm · last 6 h"
    assert shaft["orders"] == [
        ["order 1×", "2.900 Hz"],
        ["order 2×", "5.800 Hz"],
        ["order 3×", "8.700 Hz"],
        ["order 5×", "14.500 Hz"],
    ]
    assert shaft["tracks"] == [
        f"harmonic 1: 2.906 Hz on order 1×, {len(track)} blocks (last {track['block'].max()}) "
        "- not a mode"
    ]
    assert shaft["lines"] == ["order 1×", "order 2×", "order 3×", "order 5×"]
    in_window = track[track["block"] > newest - 72]
    assert shaft["points"] == len(in_window)


def test_killed_monitor_turns_from_running_to_not_responding(browser, tmp_path, serve):
    """Issue 29: a real ``workbench monitor`` is ``kill -9``'d while the page watches. The
    status line turns from green "monitor running" to red "monitor not responding" within
    two of the monitor's poll intervals (plus the page's own poll), naming the last file the
    monitor took and when, without a reload."""
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    from workbench.dashboard.state import read_heartbeat

    from ..robustness.voyage import write_voyage

    watch, state = tmp_path / "watch", tmp_path / "state"
    files = write_voyage(watch, n_files=3)
    poll_s = 0.5
    monitor = subprocess.Popen(
        [sys.executable, "-m", "workbench.cli", "monitor", "--watch", str(watch),
         "--state", str(state), "--poll", str(poll_s), "--settle", "0.1", "--foreground",
         "--block-minutes", "2", "--step-minutes", "1", "--block-rows", "10",
         "--min-order", "4", "--max-order", "16"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])},
    )  # fmt: skip
    try:
        served = serve(state, DashboardOptions(poll_seconds=0.2))
        page = browser.open(served.url)
        running = "document.getElementById('status-state').innerText === 'monitor running'"
        heartbeat = "document.getElementById('status-heartbeat').innerText"
        named = f"{heartbeat}.includes('{files[-1].name}')"
        page.wait_for(f"{running} && {named}", timeout=120)
        green = page.evaluate("getComputedStyle(document.getElementById('status-state')).color")
        assert green == "rgb(63, 185, 80)"  # --ok
        taken = read_heartbeat(state / "heartbeat.json")["last_file_taken_at"]
        page.evaluate("window.__notReloaded = 'yes'")
        monitor.send_signal(signal.SIGKILL)
        monitor.wait(timeout=30)
        killed = time.monotonic()
        page.wait_for(
            "document.getElementById('status-state').innerText === 'monitor not responding'",
            timeout=30,
        )
        # two poll intervals after the last heartbeat, then the page's next poll (0.2 s);
        # a generous margin for a busy machine, far below the 15-min silence of old
        assert time.monotonic() - killed < 2 * poll_s + 5.0
        seen = page.evaluate(READ_PAGE)
        colour = page.evaluate("getComputedStyle(document.getElementById('status-state')).color")
    finally:
        if monitor.poll() is None:
            monitor.kill()
            monitor.wait(timeout=30)
    assert colour == "rgb(248, 81, 73)" != green  # --bad, not the green of running
    assert "monitor running" not in seen["status"]
    assert f"last file taken: {files[-1].name} at {taken[11:19]}Z" in seen["status"]
    assert "no heartbeat for" in seen["status"] and "on " in seen["status"]
    assert seen["marker"] == "yes"  # the same page, never reloaded


def test_a_stopped_background_worker_is_shown(browser, tmp_path, serve):
    """The heartbeat's worker state reaches the status line: stopped in red with the
    monitor's message, a replaced worker as a note, nothing while all is well."""
    status = {
        "updated_at": pd.Timestamp.now(tz="UTC").isoformat(),
        "last_block": 7,
        "blocks_done": 8,
        "state": "running",
        "pid": 11,
        "watch": "/acc",
        "message": "",
    }
    message = "background forecast/health worker (pid 12) stopped at 2026-03-01T06:00:00Z"

    def beat(worker: dict, doing: str = "waiting for files", busy_s: float = 0.0) -> None:
        heartbeat = {
            "time": pd.Timestamp.now(tz="UTC").isoformat(),
            "pid": 11,
            "host": "pc",
            "poll_s": 600.0,
            "state": "running",
            "last_file": "acc_007.npz",
            "last_file_taken_at": "2026-03-01T05:59:00Z",
            "doing": doing,
            "doing_since": (pd.Timestamp.now(tz="UTC") - pd.Timedelta(seconds=busy_s)).isoformat(),
            "stall_s": 300.0,
            "worker": worker,
        }
        (tmp_path / "heartbeat.json").write_text(json.dumps(heartbeat))

    (tmp_path / "status.json").write_text(json.dumps(status))
    beat({"state": "alive", "pid": 12, "message": ""})
    served = serve(tmp_path, DashboardOptions(poll_seconds=0.2))
    page = browser.open(served.url)
    page.wait_for("document.getElementById('status-state').innerText === 'monitor running'")
    page.wait_for("document.getElementById('status-heartbeat').innerText !== ''")
    assert page.evaluate("document.getElementById('status-worker').innerText") == ""
    assert "last file acc_007.npz taken 2026-03-01 05:59Z" in page.evaluate(
        "document.getElementById('status').innerText"
    )
    beat({"state": "stopped", "pid": 12, "message": message})
    text = page.wait_for("document.getElementById('status-worker').innerText")
    colour = page.evaluate("getComputedStyle(document.getElementById('status-worker')).color")
    assert text == f"background worker stopped: {message}" and colour == "rgb(248, 81, 73)"
    beat({"state": "alive", "pid": 13, "message": f"{message}; replaced by pid 13"})
    page.wait_for("document.getElementById('status-worker').innerText.endsWith('pid 13')")
    colour = page.evaluate("getComputedStyle(document.getElementById('status-worker')).color")
    assert colour == "rgb(210, 153, 34)"  # --warn: a note, no longer an outage
    # the heartbeat thread beats on while the main loop hangs in one block for 7 min
    beat({"state": "alive", "pid": 13, "message": ""}, "identifying block 44", 420.0)
    page.wait_for("document.getElementById('status-state').innerText === 'monitor not responding'")
    line = page.wait_for("document.getElementById('status-heartbeat').innerText")
    assert line.startswith("main loop stuck 7 min identifying block 44 (since "), line
    assert "pid 11 on pc" in line and "last file taken: acc_007.npz" in line
