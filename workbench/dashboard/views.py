"""What each panel of the dashboard shows, as JSON-ready dictionaries.

Pure functions of the state tables: no I/O, so each panel is testable on its own. Times
are sent twice: ISO-8601 UTC text for people and epoch milliseconds for the plots.
Missing values (NaN, NaT) become ``null``, since JSON has no NaN.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

__all__ = [
    "alarms_view",
    "data_health_view",
    "health_view",
    "heartbeat_stale",
    "iso",
    "mode_references",
    "modes_view",
    "shaft_view",
    "status_view",
    "tracked_view",
]


def iso(value) -> str | None:
    """ISO-8601 UTC text of a timestamp (``2024-03-01T06:05:00Z``), None for NaT."""
    if value is None or pd.isna(value):
        return None
    stamp = pd.Timestamp(value)
    stamp = stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")
    return stamp.strftime("%Y-%m-%dT%H:%M:%SZ")


def _epoch_ms(values: pd.Series) -> list[int]:
    """Milliseconds since 1970-01-01 UTC (whatever the time resolution of *values*)."""
    elapsed = values - pd.Timestamp(0, tz="UTC")
    return (elapsed // pd.Timedelta(milliseconds=1)).astype("int64").tolist()


def _num(value) -> float | None:
    """A float for JSON: None for NaN, infinities and missing values."""
    if value is None or value is pd.NA:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _nums(values) -> list[float | None]:
    array = np.asarray(values, dtype=float)
    return [float(v) if math.isfinite(v) else None for v in array]


def _window(frame: pd.DataFrame, hours: float) -> pd.DataFrame:
    """Rows whose block starts within *hours* of the newest block's start."""
    if frame.empty:
        return frame
    newest = frame["block_start"].max()
    return frame[frame["block_start"] > newest - pd.Timedelta(hours=hours)]


#: A heartbeat older than this many of the monitor's poll intervals: not responding.
HEARTBEAT_INTERVALS = 2.0


def _utc(text: str) -> pd.Timestamp:
    stamp = pd.Timestamp(text)
    return stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")


def heartbeat_stale(
    beat_time: pd.Timestamp,
    now: pd.Timestamp,
    poll_s: float,
    *,
    intervals: float = HEARTBEAT_INTERVALS,
) -> bool:
    """Whether a heartbeat written at *beat_time* is missed at *now*.

    The monitor writes its heartbeat every *poll_s* from a timer thread of its own, so a
    heartbeat older than *intervals* poll intervals means the monitor is not responding
    (killed, hung, its machine or disk gone), whatever its ``status.json`` last said.

    Parameters
    ----------
    beat_time, now : pandas.Timestamp
        When the heartbeat was written and the time it is judged at. [UTC]
    poll_s : float
        The monitor's poll interval, as written in the heartbeat. [s]
    intervals : float
        Poll intervals a heartbeat may be late. [-]
    """
    if not (math.isfinite(poll_s) and poll_s > 0):
        raise ValueError(f"poll_s={poll_s!r} must be a positive number of seconds")
    return (now - beat_time).total_seconds() > intervals * poll_s


def status_view(
    status: dict | None, now: pd.Timestamp, heartbeat: dict | None = None
) -> dict[str, Any]:
    """The monitor's progress (``status.json``) and liveness (``heartbeat.json``) at
    *now*.

    ``liveness`` is ``"not responding"`` when the status says running and the heartbeat is
    missed (:func:`heartbeat_stale`), or when the heartbeat (written by a thread of its own)
    says the monitor's main loop has been in one activity (reading a file, identifying a
    block) longer than its ``stall_s`` (a hung loop beside a live thread); else the status's
    state (``"running"``, ``"stopped"``).
    Without a heartbeat file (a state folder written by something else than the monitor,
    such as the demo) the status's state stands as written.
    """
    if status is None:
        return {}
    updated = _utc(status["updated_at"])
    view = {
        "state": status["state"],
        "liveness": status["state"],
        "last_block": status["last_block"],
        "blocks_done": status["blocks_done"],
        "updated_at": iso(updated),
        "age_s": _num((now - updated).total_seconds()),
        "watch": status["watch"],
        "message": status["message"],
        "pid": status["pid"],
        # blocks the monitor gave up (their file came after the late window), which a
        # batch identify over the folder includes
        "given_up": [
            {key: span[key] for key in ("first_block", "last_block", "start", "end", "reason")}
            for span in status.get("given_up", [])
        ],
        "given_up_note": status.get("given_up_note", ""),
        "heartbeat": None,
    }
    if heartbeat is not None:
        beat = _utc(heartbeat["time"])
        stale = heartbeat_stale(beat, now, float(heartbeat["poll_s"]))
        # the heartbeat is written at *beat*: the main loop had then been in its activity
        # for (beat - since); it still is at *now* unless a newer heartbeat says otherwise
        since = _utc(heartbeat["doing_since"])
        busy_s = (min(now, beat) - since).total_seconds()
        stalled = busy_s > float(heartbeat["stall_s"])
        running = status["state"] == "running" and heartbeat["state"] == "running"
        if running and (stale or stalled):
            view["liveness"] = "not responding"
        elif heartbeat["state"] == "stopped":
            view["liveness"] = "stopped"
        taken = heartbeat["last_file_taken_at"]
        view["heartbeat"] = {
            "time": iso(beat),
            "age_s": _num((now - beat).total_seconds()),
            "limit_s": HEARTBEAT_INTERVALS * float(heartbeat["poll_s"]),
            "pid": heartbeat["pid"],
            "host": heartbeat["host"],
            "last_file": heartbeat["last_file"],
            "last_file_taken_at": None if taken is None else iso(_utc(taken)),
            "doing": heartbeat["doing"],
            "doing_since": iso(since),
            "busy_s": _num(busy_s),
            "stall_s": float(heartbeat["stall_s"]),
            "stalled": bool(running and stalled and not stale),
            "worker": {k: heartbeat["worker"][k] for k in ("state", "pid", "message")},
        }
    return view


def choose_option(forecast: pd.DataFrame, option: str | None) -> str | None:
    """Forecast option to show: *option* when given, else A when present, else B."""
    present = set(forecast["option"].unique())
    if option is not None:
        return option if option in present else None
    for candidate in ("A", "B"):
        if candidate in present:
            return candidate
    return None


def modes_view(
    tracked: pd.DataFrame | None, forecast: pd.DataFrame | None, *, option: str | None = None
) -> dict[str, Any]:
    """One card per mode: the newest SSI estimate, model prediction with its 95 % bounds
    and Kalman estimate.

    The newest block is the newest of either table. A mode without an estimate in it is
    shown with the block it was last seen in (``last_block``), so a mode that has gone
    quiet is visible as such rather than with an old number passed off as current.
    """
    cards: dict[int, dict[str, Any]] = {}
    newest_block = None
    newest_start = None
    shown_option = None
    if tracked is not None and not tracked.empty:
        newest_block = int(tracked["block"].max())
        newest_start = tracked["block_start"].max()
        # each mode's newest row (block and mode are unique together)
        last = tracked.loc[tracked.groupby("mode", sort=True)["block"].idxmax()]
        for row in last.itertuples(index=False):
            cards[int(row.mode)] = {
                "mode": int(row.mode),
                "last_block": int(row.block),
                "last_time": iso(row.block_start),
                "frequency_hz": _num(row.frequency_hz),
                "damping_ratio": _num(row.damping_ratio),
            }
    if forecast is not None and not forecast.empty:
        shown_option = choose_option(forecast, option)
        rows = forecast[forecast["option"] == shown_option]
        if not rows.empty:
            block = int(rows["block"].max())
            if newest_block is None or block > newest_block:
                newest_block = block
                newest_start = rows.loc[rows["block"] == block, "block_start"].iloc[0]
            newest = rows.loc[rows.groupby("mode", sort=True)["block"].idxmax()]
            for row in newest.itertuples(index=False):
                card = cards.setdefault(int(row.mode), {"mode": int(row.mode)})
                card.update(
                    {
                        "forecast_block": int(row.block),
                        "forecast_time": iso(row.block_start),
                        "phase": row.phase,
                        "ssi_frequency_hz": _num(row.ssi_frequency_hz),
                        "model_frequency_hz": _num(row.model_frequency_hz),
                        "model_lower_hz": _num(row.model_lower_hz),
                        "model_upper_hz": _num(row.model_upper_hz),
                        "kalman_frequency_hz": _num(row.kalman_frequency_hz),
                        "kalman_std_hz": _num(row.kalman_std_hz),
                    }
                )
                ssi, low, high = (
                    card["ssi_frequency_hz"],
                    card["model_lower_hz"],
                    card["model_upper_hz"],
                )
                card["inside_bounds"] = (
                    None if ssi is None or low is None or high is None else low <= ssi <= high
                )
    if forecast is not None and not forecast.empty and tracked is None:
        # no tracked table yet: the forecast's SSI column tells when a mode was identified
        rows = forecast[(forecast["option"] == shown_option) & forecast["ssi_frequency_hz"].notna()]
        for mode, group in rows.groupby("mode"):
            cards[int(mode)]["last_block"] = int(group["block"].max())
    for card in cards.values():
        card["current"] = newest_block is not None and card.get("last_block") == newest_block
        if not card["current"]:
            # an old number is not passed off as current
            card["frequency_hz"] = None
            card["damping_ratio"] = None
    return {
        "block": newest_block,
        "block_start": iso(newest_start),
        "option": shown_option,
        "modes": [cards[m] for m in sorted(cards)],
    }


#: Decimals of the relative changes sent to the page: 1e-4 % (a millionth of the
#: frequency), far below what SSI resolves, and a third of the JSON of full floats.
PERCENT_DECIMALS = 4


def _percent(values: np.ndarray, reference: float) -> list[float | None]:
    """Relative change of *values* against *reference*, in % (None for NaN)."""
    change = np.round(100.0 * (np.asarray(values, dtype=float) / reference - 1.0), PERCENT_DECIMALS)
    return [float(v) if math.isfinite(v) else None for v in change]


def mode_references(
    tracked: pd.DataFrame,
    forecast: pd.DataFrame | None = None,
    health: pd.DataFrame | None = None,
    *,
    option: str | None = None,
    modes=None,
) -> tuple[dict[int, float], str]:
    """Each mode's reference frequency, against which its relative change is shown, and
    what it is (one line for the reader).

    The first available of: the median of the mode's tracked frequency over the health
    chart's reference period (the in-control state the chart compares with); the median
    of the forecast model's prediction so far; the median of its tracked frequency so far.
    A mode without a value in the first gets it from the next.

    Parameters
    ----------
    modes : iterable of int, optional
        The modes wanted (default: all); the later sources are read only for those the
        earlier ones leave without a reference.

    Returns
    -------
    references : dict of int to float
        Mode -> reference frequency. [Hz]
    what : str
        How the references were taken ("; "-separated when several sources were used).
    """
    references: dict[int, float] = {}
    used: list[str] = []
    wanted = None if modes is None else {int(m) for m in modes}

    def missing() -> bool:
        return wanted is None or not wanted <= references.keys()

    def take(medians: pd.Series, what: str) -> None:
        for mode, value in medians.items():
            value = float(value)
            if int(mode) not in references and math.isfinite(value) and value > 0:
                if wanted is not None and int(mode) not in wanted:
                    continue
                references[int(mode)] = value
                if what not in used:
                    used.append(what)

    if health is not None and not health.empty:
        blocks = health.loc[health["phase"] == "reference", "block"].to_numpy()
        if blocks.size:
            inside = np.isin(tracked["block"].to_numpy(), blocks)
            frequency = pd.Series(tracked["frequency_hz"].to_numpy(dtype=float)[inside])
            first, last = int(blocks.min()), int(blocks.max())
            take(
                frequency.groupby(tracked["mode"].to_numpy()[inside]).median(),
                f"median over the health reference period (blocks {first}-{last})",
            )
    if forecast is not None and not forecast.empty and missing():
        shown = (forecast["option"] == choose_option(forecast, option)).to_numpy()
        model = pd.Series(forecast["model_frequency_hz"].to_numpy(dtype=float)[shown])
        take(
            model.groupby(forecast["mode"].to_numpy()[shown]).median(),
            "median of the model so far",
        )
    if missing():
        take(tracked.groupby("mode")["frequency_hz"].median(), "median tracked frequency so far")
    return references, "; ".join(used)


#: A shaft order is drawn in a mode's panel when it comes this close to the mode's
#: reference frequency in the window (relative): where a harmonic could pass for a change.
ORDER_NEAR_MODE = 0.05


def _split(frame: pd.DataFrame, key: str) -> list[tuple[int, slice]]:
    """(key value, row slice) of a frame sorted by *key*."""
    values = frame[key].to_numpy()
    if values.size == 0:
        return []
    keys, starts = np.unique(values, return_index=True)
    ends = np.append(starts[1:], values.size)
    return [(k, slice(int(a), int(b))) for k, a, b in zip(keys.tolist(), starts, ends, strict=True)]


def tracked_view(
    tracked: pd.DataFrame,
    *,
    hours: float,
    harmonics: pd.DataFrame | None = None,
    forecast: pd.DataFrame | None = None,
    health: pd.DataFrame | None = None,
    option: str | None = None,
) -> dict[str, Any]:
    """Tracked frequencies of the last *hours* before the newest block, one panel per
    mode, in relative change (%) against the mode's reference
    (:func:`mode_references`), with the forecast model's prediction and 95 % band
    (*forecast*, option *option*) in the same unit.

    Each series has the absolute ``frequency_hz`` too; its ``band`` gives the model per
    block of the window (``block``: the times are those of ``blocks``, the window's
    blocks and their start times); ``orders`` are the shaft orders (*harmonics*:
    :data:`~workbench.dashboard.state.HARMONIC_LINES`) that come within
    :data:`ORDER_NEAR_MODE` of the mode's reference in the window, in % of it (a line a
    reader must not take for the mode). ``harmonics`` lists the orders within the modes'
    frequency range (±10 %) in Hz.
    """
    # the window's rows by mode and block, as arrays (the tracked table may be long)
    start_ns = tracked["block_start"].to_numpy(dtype="datetime64[ns]")
    newest = start_ns.max() if start_ns.size else np.datetime64("NaT")
    inside = np.flatnonzero(start_ns > newest - np.timedelta64(int(hours * 3.6e12), "ns"))
    mode_all = tracked["mode"].to_numpy(dtype="int64")[inside]
    block = tracked["block"].to_numpy(dtype="int64")[inside]
    order = np.lexsort((block, mode_all))
    mode_all, block, inside = mode_all[order], block[order], inside[order]
    frequency = tracked["frequency_hz"].to_numpy(dtype=float)[inside]
    t = start_ns[inside].astype("datetime64[ms]").astype("int64")
    first = last = None
    if block.size:
        first, last = int(block.min()), int(block.max())
    groups = []
    if mode_all.size:
        keys, starts = np.unique(mode_all, return_index=True)
        ends = np.append(starts[1:], mode_all.size)
        groups = [
            (int(k), slice(int(a), int(b))) for k, a, b in zip(keys, starts, ends, strict=True)
        ]
    references, what = mode_references(
        tracked, forecast, health, option=option, modes=[mode for mode, _ in groups]
    )
    # the window's blocks and times, shared by the bands and the order lines
    times = dict(zip(block.tolist(), t.tolist(), strict=True))
    lines, near = [], []
    if harmonics is not None and not harmonics.empty and first is not None:
        low, high = 0.9 * float(np.nanmin(frequency)), 1.1 * float(np.nanmax(frequency))
        shown = harmonics[harmonics["block"].between(first, last)]
        shown = shown.sort_values(["order", "block"], kind="stable")
        order_block = shown["block"].to_numpy(dtype="int64")
        order_t = np.asarray(_epoch_ms(shown["block_start"]), dtype="int64")
        order_hz = shown["frequency_hz"].to_numpy(dtype=float)
        for order, rows in _split(shown, "order"):
            hz = order_hz[rows]
            in_range = (hz >= low) & (hz <= high)
            item = {
                "order": float(order),
                "block": order_block[rows].tolist(),
                "t": order_t[rows].tolist(),
            }
            near.append((item, hz))
            if in_range.any():
                lines.append({**item, "frequency_hz": _nums(np.where(in_range, hz, np.nan))})
    bands: dict[int, tuple[np.ndarray, ...]] = {}
    shown_option = None
    if forecast is not None and not forecast.empty and first is not None:
        shown_option = choose_option(forecast, option)
        chosen = (forecast["option"] == shown_option) & forecast["block"].between(first, last)
        wanted = ["block", "block_start", "mode"]
        wanted += ["model_frequency_hz", "model_lower_hz", "model_upper_hz"]
        rows = forecast[wanted][chosen.to_numpy()].sort_values(["mode", "block"], kind="stable")
        columns = [
            rows[c].to_numpy(dtype=float)
            for c in ("model_frequency_hz", "model_lower_hz", "model_upper_hz")
        ]
        band_block = rows["block"].to_numpy(dtype="int64")
        for mode, part in _split(rows, "mode"):
            bands[int(mode)] = (band_block[part], *(c[part] for c in columns))
        for blocks in bands.values():  # forecast blocks without a tracked estimate
            for b in blocks[0][~np.isin(blocks[0], block)].tolist():
                times.setdefault(b, None)
        missing = [b for b, v in times.items() if v is None]
        if missing:
            extra = rows[rows["block"].isin(missing)].drop_duplicates("block")
            times.update(zip(extra["block"].tolist(), _epoch_ms(extra["block_start"]), strict=True))
    series = []
    for mode, rows in groups:
        reference = references.get(int(mode))
        item = {
            "mode": int(mode),
            "block": block[rows].tolist(),
            "t": t[rows].tolist(),
            "frequency_hz": _nums(frequency[rows]),
            "reference_hz": reference,
            "change_percent": None,
            "band": None,
            "orders": [],
        }
        if reference is not None:
            item["change_percent"] = _percent(frequency[rows], reference)
            band = bands.get(int(mode))
            if band is not None and np.isfinite(band[1]).any():
                item["band"] = {
                    "block": band[0].tolist(),
                    "model_percent": _percent(band[1], reference),
                    "lower_percent": _percent(band[2], reference),
                    "upper_percent": _percent(band[3], reference),
                }
            for order, hz in near:
                relative = hz / reference - 1.0
                if np.nanmin(np.abs(relative), initial=np.inf) <= ORDER_NEAR_MODE:
                    item["orders"].append(
                        {
                            "order": order["order"],
                            "block": order["block"],
                            "t": order["t"],
                            "change_percent": _percent(hz, reference),
                        }
                    )
        series.append(item)
    ordered = sorted(times)
    return {
        "hours": hours,
        "block": int(tracked["block"].max()) if not tracked.empty else None,
        "start": iso(pd.Timestamp(start_ns[inside].min(), tz="UTC")) if block.size else None,
        "end": iso(pd.Timestamp(start_ns[inside].max(), tz="UTC")) if block.size else None,
        "reference": what,
        "option": shown_option,
        "blocks": {"block": ordered, "t": [times[b] for b in ordered]},
        "series": series,
        "harmonics": lines,
    }


def shaft_view(
    harmonics: pd.DataFrame | None,
    harmonic_tracks: pd.DataFrame | None,
    *,
    hours: float,
) -> dict[str, Any]:
    """The shaft orders and the tracked lines that are harmonics (not modes) over the
    last *hours*.

    Parameters
    ----------
    harmonics : DataFrame or None
        :data:`~workbench.dashboard.state.HARMONIC_LINES`: each order's frequency per
        block at the logged shaft speed (or the speed x the shaft rate per knot).
    harmonic_tracks : DataFrame or None
        :data:`~workbench.dashboard.state.HARMONIC_TRACKS`: the identified lines the
        tracking recognised as shaft or blade-pass harmonics and kept out of the modes.
    """
    newest_block = None
    newest_start = None
    for table in (harmonics, harmonic_tracks):
        if table is not None and not table.empty:
            block = int(table["block"].max())
            if newest_block is None or block > newest_block:
                newest_block = block
                newest_start = table.loc[table["block"] == block, "block_start"].iloc[0]
    view: dict[str, Any] = {
        "hours": hours,
        "block": newest_block,
        "block_start": iso(newest_start),
        "shaft_rpm": None,
        "orders": [],
        "tracks": [],
    }
    if newest_block is None:
        return view
    cut = newest_start - pd.Timedelta(hours=hours)
    if harmonics is not None and not harmonics.empty:
        lines = harmonics[harmonics["block_start"] > cut].sort_values("block")
        newest = harmonics[harmonics["block"] == int(harmonics["block"].max())]
        rpm = newest["frequency_hz"] / newest["order"] * 60.0
        view["shaft_rpm"] = _num(rpm.median()) if len(rpm) else None
        now = newest.set_index("order")["frequency_hz"]
        for order, rows in lines.groupby("order", sort=True):
            view["orders"].append(
                {
                    "order": float(order),
                    "frequency_hz": _num(now.get(order)),
                    "block": rows["block"].astype(int).tolist(),
                    "t": _epoch_ms(rows["block_start"]),
                    "line_hz": _nums(rows["frequency_hz"]),
                }
            )
    if harmonic_tracks is not None and not harmonic_tracks.empty:
        for track, rows in harmonic_tracks.sort_values("block").groupby("track", sort=True):
            orders = rows["order"].dropna()
            recent = rows[rows["block_start"] > cut]
            view["tracks"].append(
                {
                    "track": int(track),
                    "median_frequency_hz": _num(rows["frequency_hz"].median()),
                    "blocks": len(rows),
                    "order": _num(orders.mode().iloc[0]) if len(orders) else None,
                    "last_block": int(rows["block"].max()),
                    "block": recent["block"].astype(int).tolist(),
                    "t": _epoch_ms(recent["block_start"]),
                    "frequency_hz": _nums(recent["frequency_hz"]),
                }
            )
    return view


def health_view(health: pd.DataFrame, *, hours: float) -> dict[str, Any]:
    """The control chart over the last *hours*: statistic, limit, phase and alarms."""
    full = health.sort_values("block")
    window = _window(full, hours)
    reference = full[full["phase"] == "reference"]
    newest = full.iloc[-1] if not full.empty else None
    # share of the statistic per mode in the newest block (``contribution_<mode>`` columns of
    # :func:`workbench.shm.health_chart`, when the table has them)
    contributions = []
    if newest is not None:
        for column in full.columns:
            if column.startswith("contribution_") and column[13:].isdigit():
                share = _num(newest[column])
                if share is not None:
                    contributions.append({"mode": int(column[13:]), "share": share})
        contributions.sort(key=lambda c: -c["share"])
    return {
        "hours": hours,
        "block": None if newest is None else int(newest["block"]),
        "statistic": None if newest is None else _num(newest["statistic"]),
        "limit": None if newest is None else _num(newest["limit"]),
        "phase": None if newest is None else newest["phase"],
        "alarm": None if newest is None else bool(newest["alarm"]),
        "n_modes": None if newest is None else int(newest["n_modes"]),
        "contributions": contributions,
        "reference_start": iso(reference["block_start"].min()) if not reference.empty else None,
        "reference_end": iso(reference["block_start"].max()) if not reference.empty else None,
        "points": {
            "block": window["block"].astype(int).tolist(),
            "t": _epoch_ms(window["block_start"]),
            "statistic": _nums(window["statistic"]),
            "limit": _nums(window["limit"]),
            "alarm": window["alarm"].astype(bool).tolist(),
            "reference": (window["phase"] == "reference").tolist(),
        },
    }


def alarms_view(alarms: pd.DataFrame, health: pd.DataFrame | None = None) -> dict[str, Any]:
    """Alarm episodes, newest first; an episode is active when it reaches the newest
    block of the health chart and that block alarms."""
    active_block = None
    if health is not None and not health.empty:
        newest = health.sort_values("block").iloc[-1]
        if bool(newest["alarm"]):
            active_block = int(newest["block"])
    episodes = []
    for row in alarms.sort_values("start_block", ascending=False).itertuples(index=False):
        episodes.append(
            {
                "alarm": int(row.alarm),
                "start_block": int(row.start_block),
                "end_block": int(row.end_block),
                "start_time": iso(row.start_time),
                "end_time": iso(row.end_time),
                "peak_block": int(row.peak_block),
                "peak_statistic": _num(row.peak_statistic),
                "limit": _num(row.limit),
                "modes": row.modes,
                "top_mode": int(row.top_mode),
                "top_mode_shift_percent": _num(row.top_mode_shift_percent),
                "active": active_block is not None and int(row.end_block) == active_block,
            }
        )
    return {
        "count": len(episodes),
        "active": any(e["active"] for e in episodes),
        "alarms": episodes,
    }


def data_health_view(data_health: pd.DataFrame, *, hours: float) -> dict[str, Any]:
    """The newest block's acquisition health and a summary over the last *hours*:
    latency (median, worst), blocks with dropped channels, total gaps."""
    window = _window(data_health.sort_values("block"), hours)
    if window.empty:
        return {"hours": hours, "latest": None, "summary": None, "rows": []}

    def row_dict(row) -> dict[str, Any]:
        dropped = row.dropped_channels if isinstance(row.dropped_channels, str) else ""
        return {
            "block": int(row.block),
            "block_start": iso(row.block_start),
            "n_channels": int(row.n_channels),
            "dropped_channels": [c.strip() for c in dropped.split(",") if c.strip()],
            "gap_seconds": _num(row.gap_seconds),
            "last_file_landed": iso(row.last_file_landed),
            "identified_at": iso(row.identified_at),
            "latency_s": _num(row.latency_s),
        }

    rows = [row_dict(r) for r in window.itertuples(index=False)]
    latency = window["latency_s"].to_numpy(dtype=float)
    latency = latency[np.isfinite(latency)]
    dropped = window["dropped_channels"].fillna("").str.strip() != ""
    return {
        "hours": hours,
        "latest": rows[-1],
        "summary": {
            "blocks": len(rows),
            "median_latency_s": _num(np.median(latency)) if latency.size else None,
            "worst_latency_s": _num(latency.max()) if latency.size else None,
            "blocks_with_dropped_channels": int(dropped.sum()),
            "gap_seconds": _num(window["gap_seconds"].sum()),
        },
        "rows": rows[::-1][:12],
    }
