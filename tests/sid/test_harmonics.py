"""Shaft and blade-pass harmonics: marks from the shaft speed and from speed-following.

Reference values are analytic: with a constant shaft speed n the order k sits at exactly
k n / 60 (all its energy there); with a shaft speed ramping linearly from 0 to N over the
block and the energy weighted by n⁴, the share of the order within a band [a, b] of
frequencies is (b⁵ - a⁵) / F⁵, F = k N / 60.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from data_contracts import SELECTED, read_dship, shape_columns
from workbench.sid.harmonics import (
    HarmonicMarker,
    HarmonicOptions,
    block_shaft_table,
    mark_harmonics,
    mark_shaft_orders,
    mark_speed_following,
)
from workbench.sid.tracking import TrackingOptions, track_modes

CHANNELS = [f"c{j}" for j in range(6)]
START = pd.Timestamp("2024-03-01T00:00:00Z")
SHAPE_MODE = np.array([1.0, 0.8, 0.3, -0.3, -0.8, -1.0])
SHAPE_FORCED = np.array([1.0, 0.6, 0.35, 0.2, 0.1, 0.05])


def _selected(rows) -> pd.DataFrame:
    """Selected-modes table of (block, frequency [Hz], shape) rows, 20-min blocks end to end."""
    frame = pd.DataFrame(
        {
            "block": [b for b, _, _ in rows],
            "block_start": [START + pd.Timedelta(minutes=20 * b) for b, _, _ in rows],
            "block_end": [START + pd.Timedelta(minutes=20 * b + 20) for b, _, _ in rows],
            "frequency_hz": [f for _, f, _ in rows],
            "damping_ratio": 0.01,
        }
    )
    shapes = np.array([s / np.linalg.norm(s) for _, _, s in rows])
    re, im = shape_columns(CHANNELS)[: len(CHANNELS)], shape_columns(CHANNELS)[len(CHANNELS) :]
    for j, (r, i) in enumerate(zip(re, im, strict=True)):
        frame[r] = shapes[:, j]
        frame[i] = 0.0
    return frame


def _log(rpm_of_second, seconds: int, speed_of_second=None) -> pd.DataFrame:
    t = np.arange(seconds)
    log = pd.DataFrame({"time": START + pd.to_timedelta(t, unit="s")})
    log["shaft_rpm"] = rpm_of_second(t)
    if speed_of_second is not None:
        log["speed_kn"] = speed_of_second(t)
    return log


def test_constant_shaft_speed_marks_each_order_and_the_blade_pass():
    selected = _selected(
        [
            (0, 3.0, SHAPE_FORCED),  # order 1 of 180 rpm
            (0, 2.85, SHAPE_MODE),  # 5 % below it: a mode
            (0, 6.03, SHAPE_FORCED),  # order 2, 0.5 % off
            (0, 15.0, SHAPE_FORCED),  # blade pass of 5 blades
            (0, 7.4, SHAPE_MODE),
        ]
    )
    log = _log(lambda t: np.full(t.shape, 180.0), 1200)
    marks = mark_shaft_orders(selected, log, HarmonicOptions(blades=5))
    assert marks.tolist()[0] == 1.0 and marks.tolist()[2] == 2.0 and marks.tolist()[3] == 5.0
    assert np.isnan(marks.iloc[1]) and np.isnan(marks.iloc[4])
    # without the blade count, the blade pass (order 5) is not checked
    assert np.isnan(mark_shaft_orders(selected, log, HarmonicOptions()).iloc[3])


@pytest.mark.parametrize(("min_share", "marked"), [(0.152, True), (0.158, False)])
def test_ramp_share_is_the_energy_weighted_analytic_value(min_share, marked):
    # shaft speed 0 -> 180 rpm linearly over the block: order 1 sweeps 0 -> 3 Hz; the
    # share within ±2 % of 2.85 Hz is (2.907⁵ - 2.793⁵) / 3⁵ = 0.1549
    a, b, top = 2.85 * 0.98, 2.85 * 1.02, 3.0
    assert (b**5 - a**5) / top**5 == pytest.approx(0.1549, abs=1e-4)
    selected = _selected([(0, 2.85, SHAPE_MODE)])
    log = _log(lambda t: 180.0 * t / 1200.0, 1200)
    mark = mark_shaft_orders(selected, log, HarmonicOptions(orders=(1,), min_share=min_share))
    assert bool(mark.iloc[0] == 1.0) is marked


def test_a_heavily_damped_pole_counts_the_energy_within_its_bandwidth():
    # ramp 0 -> 180 rpm: within ±2 % of 2.4 Hz lies (2.448⁵ - 2.352⁵) / 3⁵ = 0.066 of the
    # order's energy, within ±ζ = ±7 % of it (2.568⁵ - 2.232⁵) / 3⁵ = 0.232
    assert (2.448**5 - 2.352**5) / 3.0**5 == pytest.approx(0.0656, abs=1e-4)
    assert (2.568**5 - 2.232**5) / 3.0**5 == pytest.approx(0.2316, abs=1e-4)
    selected = _selected([(0, 2.4, SHAPE_FORCED), (0, 2.4, SHAPE_FORCED)])
    selected["damping_ratio"] = [0.01, 0.07]
    log = _log(lambda t: 180.0 * t / 1200.0, 1200)
    marks = mark_shaft_orders(selected, log, HarmonicOptions(orders=(1,)))
    assert np.isnan(marks.iloc[0]) and marks.iloc[1] == 1.0


def test_block_without_logged_shaft_speed_is_not_marked():
    selected = _selected([(0, 3.0, SHAPE_FORCED), (8, 3.0, SHAPE_FORCED)])
    log = _log(lambda t: np.full(t.shape, 180.0), 1200)  # covers block 0 only
    marks = mark_shaft_orders(selected, log)
    assert marks.iloc[0] == 1.0 and np.isnan(marks.iloc[1])


def _voyage_rows():
    """12 blocks at 5..10 kn: a forced response at 0.3 Hz/kn (shape fixed) and a mode at
    2.9 Hz (its own shape)."""
    speeds = np.linspace(5.0, 10.0, 12)
    rows = []
    for k, v in enumerate(speeds):
        rows.append((k, 0.3 * v, SHAPE_FORCED))
        rows.append((k, 2.9, SHAPE_MODE))
    return speeds, rows


def test_speed_following_marks_the_forced_response_not_the_mode():
    speeds, rows = _voyage_rows()
    selected = _selected(rows)
    block_speed = np.repeat(speeds, 1200)
    log = _log(lambda t: np.full(t.shape, np.nan), len(block_speed), lambda t: block_speed[t])
    shaft = block_shaft_table(log.drop(columns="shaft_rpm"), selected)
    np.testing.assert_allclose(shaft["speed_energy_kn"], speeds)
    marks = mark_speed_following(selected, shaft)
    forced = selected.index[::2]
    assert (marks[forced] == 0.0).all()
    # the mode is marked only where an order's ratio (k x 0.3 Hz/kn, k = 1, 2, 3) puts it
    # on the mode: 2.9 Hz / v within 3 % of 0.3 Hz/kn, i.e. the block at 9.55 kn
    crossed = np.abs(np.log(2.9 / speeds / 0.3)) <= 0.03
    assert crossed.sum() == 1
    np.testing.assert_array_equal(marks.drop(forced).notna().to_numpy(), crossed)
    # the same through mark_harmonics, which falls back to it without a shaft speed
    result = mark_harmonics(selected, selected.iloc[:0], log.drop(columns="shaft_rpm"))
    assert result.method == "speed"
    assert result.selected["harmonic"].notna().sum() == len(forced) + 1


def test_speed_following_needs_a_sweep():
    # the forced response at one speed only: its frequency does not move, nothing marked
    rows = [(k, 3.0, SHAPE_FORCED) for k in range(12)]
    selected = _selected(rows)
    log = _log(lambda t: np.full(t.shape, np.nan), 12 * 1200, lambda t: np.full(t.shape, 10.0))
    shaft = block_shaft_table(log.drop(columns="shaft_rpm"), selected)
    assert mark_speed_following(selected, shaft).isna().all()


def _long_voyage(n_blocks: int, seed: int = 0):
    """Selected modes of *n_blocks* blocks, the speed swinging between 3 and 11 kn: orders 1
    and 2 at 0.3 Hz/kn (fixed shapes) and modes at 2.9, 4.6 and 7.5 Hz (their own shapes),
    frequencies and shapes with noise (0.3 %, 0.05); and the blocks' speed table."""
    rng = np.random.default_rng(seed)
    blocks = np.arange(n_blocks)
    speed = 7.0 + 4.0 * np.sin(2 * np.pi * blocks / 40) + 0.1 * rng.standard_normal(n_blocks)
    lines = [
        (lambda v: 0.3 * v, SHAPE_FORCED),
        (lambda v: 0.6 * v, np.array([0.2, 1.0, 0.4, -0.5, 0.3, 0.1])),
        (lambda v: 2.9, SHAPE_MODE),
        (lambda v: 4.6, np.array([1.0, -1.0, 0.5, 0.5, -1.0, 1.0])),
        (lambda v: 7.5, np.array([0.1, 0.3, 1.0, 1.0, 0.3, 0.1])),
    ]
    rows = [
        (b, f(v) * (1 + 0.003 * rng.standard_normal()), shape + 0.05 * rng.standard_normal(6))
        for b, v in zip(blocks, speed, strict=True)
        for f, shape in lines
    ]
    return _selected(rows), pd.DataFrame({"block": blocks, "speed_energy_kn": speed})


def _speed_following_by_definition(selected, shaft, options):
    """The speed-following test as its docstring defines it, every pair compared: per mode,
    the component of its shape graph (MAC >= mac_min) within its ratio window."""
    from scipy.sparse.csgraph import connected_components

    from workbench.sid.harmonics import _shapes, order_list

    speed = selected["block"].map(shaft.set_index("block")["speed_energy_kn"]).to_numpy(float)
    rows = np.flatnonzero(speed > options.min_speed_kn)
    frequency = selected["frequency_hz"].to_numpy(float)[rows]
    ratio = np.log(frequency / speed[rows])
    shapes = _shapes(selected.iloc[rows])
    linked = np.abs(shapes @ shapes.conj().T) ** 2 >= options.mac_min
    swept = np.zeros(len(rows), dtype=bool)
    for i in range(len(rows)):
        window = np.flatnonzero(np.abs(ratio - ratio[i]) <= options.ratio_tol)
        _, component = connected_components(linked[np.ix_(window, window)], directed=False)
        members = window[component == component[np.searchsorted(window, i)]]
        swept[i] = len(members) >= options.min_rows and (
            frequency[members].max() / frequency[members].min() - 1 > options.min_sweep
        )
    marked = swept.copy()
    base = np.exp(ratio[swept].min())
    for order in order_list(options):
        marked |= np.abs(ratio - np.log(base * order / min(options.orders))) <= options.ratio_tol
    return set(selected.index[rows[marked]]), base / min(options.orders)


@pytest.mark.parametrize("balls_from_rows, chunk_rows", [(10**9, 256), (8, 8)])
def test_speed_following_equals_its_definition_at_once_and_block_by_block(
    balls_from_rows, chunk_rows, monkeypatch
):
    # every pair of a window compared; or its groups from balls of shapes, and two balls'
    # members from balls within them
    from workbench.sid import harmonics

    monkeypatch.setattr(harmonics, "_BALLS_FROM_ROWS", balls_from_rows)
    monkeypatch.setattr(harmonics, "_CHUNK_ROWS", chunk_rows)
    selected, shaft = _long_voyage(120)
    options = HarmonicOptions()
    expected, per_kn = _speed_following_by_definition(selected, shaft, options)
    # not vacuous: both orders (240 rows) and 27 rows of the modes, where an order's ratio
    # is theirs
    assert len(expected) == 267
    marks = mark_speed_following(selected, shaft, options)
    assert set(marks.index[marks.notna()]) == expected
    assert marks.attrs["shaft_hz_per_kn"] == pytest.approx(per_kn, rel=1e-12)
    test = harmonics.SpeedFollowing(options)
    speed = selected["block"].map(shaft.set_index("block")["speed_energy_kn"]).to_numpy()
    for _, rows in selected.groupby("block").indices.items():
        part = selected.iloc[rows]
        test.add(part["frequency_hz"].to_numpy(), speed[rows], harmonics._shapes(part))
    marked, by_blocks = test.marked()
    assert set(selected.index[marked]) == expected and by_blocks == marks.attrs["shaft_hz_per_kn"]


def test_speed_following_memory_grows_with_the_modes_not_their_pairs():
    # 4000 modes (800 blocks): every pair's MAC alone would take 4000² x 16 B = 256 MB
    import tracemalloc

    selected, shaft = _long_voyage(800, seed=1)
    tracemalloc.start()
    marks = mark_speed_following(selected, shaft)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak < 20e6  # 3.2 MB (the modes, their windows' groups, chunks of 256 modes)
    orders = np.tile(np.arange(5) < 2, 800)  # rows 0 and 1 of each block are the orders
    assert marks[orders].notna().all()
    # the modes only where an order's ratio is theirs: 194 of their 2400 rows
    assert marks[~orders].notna().sum() == 194


def test_without_a_log_nothing_is_marked_and_the_columns_exist():
    _, rows = _voyage_rows()
    selected = _selected(rows)
    result = mark_harmonics(selected, selected.iloc[:0].assign(model_order=[]), None)
    assert result.method == "none"
    assert result.selected["harmonic"].isna().all()
    SELECTED.validate(result.selected)


def test_tracking_drops_the_harmonic_label_and_keeps_the_crossed_mode():
    speeds, rows = _voyage_rows()
    selected = _selected(rows)
    log = _log(
        lambda t: 18.0 * np.repeat(speeds, 1200)[t], 12 * 1200
    )  # rpm = 60 x 0.3 Hz/kn x speed
    selected["harmonic"] = mark_shaft_orders(selected, log)
    # order 1 passes the mode (2.9 Hz) at 9.67 kn: the block at 9.55 kn is within 2 %
    assert selected["harmonic"].iloc[::2].eq(1.0).all()
    tracked = track_modes(selected, options=TrackingOptions(frequency_tol=0.5))
    assert tracked["mode"].nunique() == 1
    assert tracked["frequency_hz"].eq(2.9).all() and len(tracked) == 12
    assert "harmonic" not in tracked.columns
    assert [h["blocks"] for h in tracked.attrs["harmonic_labels"]] == [12]


def test_options_are_checked():
    with pytest.raises(ValueError, match="blades") as error:
        HarmonicOptions(blades=-1)
    assert "at least 0" in str(error.value)
    with pytest.raises(ValueError, match="orders"):
        HarmonicOptions(orders=(0.0,))
    with pytest.raises(ValueError, match="harmonic_share"):
        TrackingOptions(harmonic_share=0.0)


def test_cli_identify_with_the_ship_log_marks_and_writes_the_shaft_table(tmp_path, capsys):
    from workbench.cli import main

    voyage = tmp_path / "voyage"
    assert main(["simulate", "--out", str(voyage), "--hours", "0.5", "--quiet"]) == 0
    out = tmp_path / "identify"
    common = ["--band", "2", "12", "--max-order", "30", "--scheduler", "synchronous", "--quiet"]
    argv = ["identify", str(voyage / "accelerations"), "--out", str(out), *common]
    assert main([*argv, "--dship", str(voyage / "dship.tsv"), "--blades", "5"]) == 0
    assert "orders 1, 2, 3, 5, 10 of the logged shaft speed" in capsys.readouterr().out
    shaft = pd.read_csv(out / "shaft.csv")
    log = read_dship(voyage / "dship.tsv")
    first = log[log["time"] < log["time"].iloc[0] + pd.Timedelta(minutes=20)]
    rpm = first["shaft_rpm"].abs()  # weighted by rpm⁴, where the harmonics' energy is
    assert shaft["shaft_rpm"].iloc[0] == pytest.approx((rpm**5).sum() / (rpm**4).sum())
    selected = SELECTED.validate(pd.read_parquet(out / "selected.parquet"))
    assert "harmonic" in selected.columns
    assert "harmonic" in pd.read_parquet(out / "poles.parquet").columns
    # a bad order list is a usage error; a log that is not one is bad data, one line
    assert main([*argv, "--dship", str(voyage / "dship.tsv"), "--harmonic-orders", "0"]) == 2
    assert "--harmonic-orders" in capsys.readouterr().err
    (tmp_path / "log.tsv").write_text("nothing here\n", encoding="utf-8")
    assert main([*argv, "--dship", str(tmp_path / "log.tsv")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "log.tsv" in err[0]


def test_a_mode_an_order_sits_on_is_kept_because_it_does_not_follow_the_order():
    # 20 blocks at 9.85-10.15 kn: order 1 (0.29 Hz/kn) sits within ±1.5 % of the mode at
    # 2.9 Hz in 13 of them (marked), the order is elsewhere in the other 7; the mode stays
    # at 2.9 Hz while the order's frequency follows the shaft (slope 0), the harmonic
    # follows it (slope 1)
    speeds = np.linspace(9.85, 10.15, 20)
    rows = []
    for k, v in enumerate(speeds):
        rows.append((k, 0.29 * v * 1.01, SHAPE_FORCED))
        rows.append((k, 2.9, SHAPE_MODE))
    selected = _selected(rows)
    selected["harmonic"] = 1.0
    selected["harmonic_frequency_hz"] = np.repeat(0.29 * speeds, 2)
    away = selected.index[1::2][13:]  # the mode's last 7 rows: no order near it
    selected.loc[away, ["harmonic", "harmonic_frequency_hz"]] = np.nan
    tracked = track_modes(selected, options=TrackingOptions(frequency_tol=0.5))
    assert tracked["frequency_hz"].eq(2.9).all() and len(tracked) == 20
    assert [h["blocks"] for h in tracked.attrs["harmonic_labels"]] == [20]
    # without the order's frequency the majority rule alone drops both
    tracked = track_modes(selected.drop(columns="harmonic_frequency_hz"))
    assert tracked.empty
    # marked in every block, the mode is taken for a harmonic: nothing tells them apart
    selected["harmonic"] = 1.0
    assert track_modes(selected, options=TrackingOptions(frequency_tol=0.5)).empty


def _noisy_log(seconds: int, rpm: float, speed_kn: float | None, seed: int = 0) -> pd.DataFrame:
    """A ship log of a steady shaft speed as a sensor logs it: 0.2 rpm of noise, 0.1 rpm
    resolution (and the speed: 0.1 kn noise and resolution)."""
    rng = np.random.default_rng(seed)
    log = _log(lambda t: np.round(rpm + 0.2 * rng.standard_normal(t.shape), 1), seconds)
    if speed_kn is not None:
        log["speed_kn"] = np.round(speed_kn + 0.1 * rng.standard_normal(seconds), 1)
    return log


def _mode_and_harmonic(blocks) -> pd.DataFrame:
    # order 1 of 180 rpm at 3.0 Hz and a mode 5 % below it, in every block
    return _selected(
        [(b, f, s) for b in blocks for f, s in ((3.0, SHAPE_FORCED), (2.85, SHAPE_MODE))]
    )


def test_a_frozen_shaft_speed_is_left_out_and_the_speed_stands_in():
    # 180 rpm at 10 kn (18 rpm/kn); the sensor freezes at 171 rpm from 40 min to 100 min
    # (blocks 2-4): order 1 of 171 rpm is 2.85 Hz, the mode's frequency. Before, the mode
    # was marked as order 1 in blocks 2-4 and the harmonic at 3.0 Hz was not.
    log = _noisy_log(6 * 1200, 180.0, 10.0)
    log.loc[2399:5999, "shaft_rpm"] = 171.0
    selected = _mode_and_harmonic(range(6))
    result = mark_harmonics(selected, selected.iloc[:0], log, HarmonicOptions())
    marks = result.selected
    assert marks.loc[marks["frequency_hz"] == 3.0, "harmonic"].eq(1.0).all()
    assert marks.loc[marks["frequency_hz"] == 2.85, "harmonic"].isna().all()
    assert marks["harmonic_checked"].all()
    assert result.shaft["shaft_rpm_from"].tolist() == ["log", "log"] + ["speed"] * 3 + ["log"]
    # the blocks of the frozen hour at the speed's 10 kn x 18 rpm/kn (0.1 kn noise)
    assert result.shaft["shaft_rpm"].iloc[2:5].to_numpy() == pytest.approx(180.0, abs=1.0)
    marker = HarmonicMarker(log)
    marker.mark_selected(selected)
    assert marker.rpm_per_kn == pytest.approx(18.0, abs=0.1)
    assert marker.unmarked()[0] == (
        "ship log: shaft speed frozen at 171 rpm from 2024-03-01 00:39:59 for 60 min: "
        "readings left out"
    )
    # without the speed, the frozen hour's blocks are not checked (and nothing is marked)
    marks = mark_harmonics(selected, selected.iloc[:0], log.drop(columns="speed_kn")).selected
    assert marks.groupby("block")["harmonic_checked"].first().tolist() == [True, True] + [
        False
    ] * 3 + [True]
    assert marks.loc[marks["block"].between(2, 4), "harmonic"].isna().all()


def test_a_shaft_speed_spike_does_not_hide_the_harmonic():
    # one reading of 1800 rpm in block 1 weighs (1800 / 180)⁴ = 10⁴ readings: before, it
    # held 89 % of the block's order energy, the harmonic at 3.0 Hz had 11 % (under 20 %)
    # and the block's shaft speed was 1622 rpm
    log = _noisy_log(3 * 1200, 180.0, None)
    log.loc[1800, "shaft_rpm"] = 1800.0
    selected = _mode_and_harmonic(range(3))
    result = mark_harmonics(selected, selected.iloc[:0], log)
    assert result.selected.loc[::2, "harmonic"].eq(1.0).all()
    assert result.shaft["shaft_rpm"].to_numpy() == pytest.approx(180.0, abs=0.1)
    assert result.shaft["shaft_rpm_from"].eq("log").all()


def test_a_line_seen_only_where_the_log_fails_is_not_tracked():
    # the log (shaft speed only) ends after block 5 of 12; a line at 4.0 Hz with the forced
    # shape appears in blocks 6-11 (after the log ended: a harmonic or not, the log cannot
    # tell). Before: tracked as a second mode (6 blocks). The mode at 2.9 Hz, seen unmarked
    # in the 6 logged blocks, keeps its 12 rows.
    log = _noisy_log(6 * 1200, 180.0, None)
    rows = [(b, 2.9, SHAPE_MODE) for b in range(12)] + [
        (b, 4.0, SHAPE_FORCED) for b in range(6, 12)
    ]
    marks = mark_harmonics(_selected(rows), _selected(rows).iloc[:0], log).selected
    tracked = track_modes(marks, options=TrackingOptions())
    assert tracked["mode"].nunique() == 1
    assert tracked["frequency_hz"].eq(2.9).all() and len(tracked) == 12
    assert marks.groupby("block")["harmonic_checked"].first().tolist() == [True] * 6 + [False] * 6
    assert "harmonic_checked" not in tracked.columns
    left_out = tracked.attrs["harmonic_labels"]
    assert [(h["blocks"], h["frequency_hz"], h["unverified"]) for h in left_out] == [(6, 4.0, True)]


def test_a_mode_seen_throughout_a_voyage_whose_log_covers_two_blocks_is_kept():
    # the log covers blocks 0-1 of 40; the mode at 2.9 Hz is seen in every block, so it is
    # checked as often as the voyage is (5 %) and is a mode, not a line seen only where the
    # log fails. A rule on the label's checked blocks alone (fewer than 10) dropped it: the
    # tracked table was empty, every mode of such a voyage lost.
    log = _noisy_log(2 * 1200, 180.0, None)
    rows = [(b, 2.9, SHAPE_MODE) for b in range(40)]
    marks = mark_harmonics(_selected(rows), _selected(rows).iloc[:0], log).selected
    assert int(marks.groupby("block")["harmonic_checked"].first().sum()) == 2
    tracked = track_modes(marks, options=TrackingOptions())
    assert len(tracked) == 40 and tracked["frequency_hz"].eq(2.9).all()
    assert tracked.attrs["harmonic_labels"] == []


def test_a_harmonic_line_through_an_outage_is_not_seen_away_from_its_order():
    # a voyage of 64 blocks, a mode at 2.9 Hz in all; a line at 6.0 Hz with the forced
    # shape in blocks 0-29 (under half of them: a line that comes and goes), marked as
    # order 2 in its 18 checked blocks (0-8 and 21-29, speed ramps: the order's
    # energy-weighted frequency 5.75-6.08 Hz does not move with the pole's, slope 0),
    # unchecked in blocks 9-20 (every column of the log empty). Before, its 12 unchecked
    # rows counted as seen away from the orders (over a quarter of its blocks) and, not
    # following its order, the line was kept as a mode an order sits on (ramps seed 0,
    # 'all nan 1.25-2.75 h'). The mode, checked and unmarked, keeps its 64 rows.
    rng = np.random.default_rng(3)
    rows = [(b, 2.9, SHAPE_MODE) for b in range(64)] + [(b, 6.0, SHAPE_FORCED) for b in range(30)]
    selected = _selected(rows)
    line = selected["frequency_hz"].eq(6.0).to_numpy()
    checked = ~selected["block"].between(9, 20).to_numpy()
    selected["harmonic_checked"] = checked
    selected["harmonic"] = np.where(line & checked, 2.0, np.nan)
    selected["harmonic_frequency_hz"] = np.where(
        line & checked, rng.uniform(5.75, 6.08, len(selected)), np.nan
    )
    tracked = track_modes(selected, options=TrackingOptions())
    assert tracked["frequency_hz"].eq(2.9).all() and len(tracked) == 64
    left_out = tracked.attrs["harmonic_labels"]
    assert [(h["blocks"], h["frequency_hz"], h["unverified"]) for h in left_out] == [
        (30, 6.0, False)
    ]
    # checked and unmarked in blocks 0-7 (over a quarter of its checked blocks): seen
    # away from its order (10 of 18 checked rows marked), and not following it: a mode an
    # order sits on, kept
    away = line & selected["block"].between(0, 7).to_numpy()
    selected.loc[away, ["harmonic", "harmonic_frequency_hz"]] = np.nan
    tracked = track_modes(selected, options=TrackingOptions())
    assert len(tracked) == 94 and tracked.attrs["harmonic_labels"] == []


def test_a_mode_seen_throughout_an_order_sits_on_is_kept_through_an_outage():
    # a mode at 8.2 Hz seen in all 69 blocks, marked as order 2 in 41 of its 52 checked
    # blocks (order 2 sits on it at two speeds: its marks 8.0-8.4 Hz, slope 0) and
    # unchecked in 17 (every column of the log empty): unmarked in 28 of its blocks, seen
    # away from its order, kept (sitting seed 1, 'all nan 3-4.5 h'; a rule counting only
    # its checked rows as seen away, 11 of 69, dropped it)
    rng = np.random.default_rng(4)
    selected = _selected([(b, 8.2, SHAPE_MODE) for b in range(69)])
    checked = ~selected["block"].between(35, 51).to_numpy()
    marked = checked & (np.cumsum(checked) <= 41)
    selected["harmonic_checked"] = checked
    selected["harmonic"] = np.where(marked, 2.0, np.nan)
    selected["harmonic_frequency_hz"] = np.where(marked, rng.uniform(8.0, 8.4, 69), np.nan)
    tracked = track_modes(selected, options=TrackingOptions())
    assert len(tracked) == 69 and tracked.attrs["harmonic_labels"] == []


def test_a_line_seen_in_part_of_the_voyage_is_judged_by_its_few_checked_rows():
    # the log covers blocks 36-39 of 40 (its last 45 min); a line at 5.6 Hz with the forced
    # shape in blocks 30-38, marked as order 2 in its 3 checked blocks (36-38), unchecked in
    # 30-35. Before, 3 checked rows were too few (their 95 % lower bound 0.44, under a half)
    # and the line was tracked as a mode (sitting seed 0, 'only the last 45 min'). The mode
    # at 2.9 Hz, seen in all 40 blocks and marked in 3 of its 4 checked ones (an order near
    # it there), is judged by all its rows (3 of 40 marked) and keeps its 40 rows.
    rows = [(b, 2.9, SHAPE_MODE) for b in range(40)] + [
        (b, 5.6, SHAPE_FORCED) for b in range(30, 39)
    ]
    selected = _selected(rows)
    line = selected["frequency_hz"].eq(5.6).to_numpy()
    checked = (selected["block"] >= 36).to_numpy()
    selected["harmonic_checked"] = checked
    marked = checked & (line | (selected["block"] < 39).to_numpy())
    selected["harmonic"] = np.where(marked, np.where(line, 2.0, 1.0), np.nan)
    selected["harmonic_frequency_hz"] = np.where(marked, selected["frequency_hz"], np.nan)
    tracked = track_modes(selected, options=TrackingOptions())
    assert len(tracked) == 40 and tracked["frequency_hz"].eq(2.9).all()
    left_out = tracked.attrs["harmonic_labels"]
    assert [(h["blocks"], h["frequency_hz"], h["share"]) for h in left_out] == [(9, 5.6, 1.0)]


def test_a_mode_seen_throughout_a_voyage_marked_in_every_checked_block_is_kept():
    # the log covers blocks 32-39 of 40 (its last 45 min), where an order sits on the mode
    # at 2.9 Hz: its 8 checked rows are all marked, its 32 others unchecked. A harmonic
    # would need the shaft at one rate through the voyage; 8 of 40 rows shown on the order
    # make a mode. Before, the 8 checked rows judged it (their 95 % lower bound 0.68) and
    # the mode was dropped as a harmonic (sitting seed 1, 'only the last 45 min': modes 1
    # and 7, which orders 1 and 2 sit on at 7 kn).
    selected = _selected([(b, 2.9, SHAPE_MODE) for b in range(40)])
    checked = (selected["block"] >= 32).to_numpy()
    selected["harmonic_checked"] = checked
    selected["harmonic"] = np.where(checked, 1.0, np.nan)
    selected["harmonic_frequency_hz"] = np.where(checked, 2.88, np.nan)
    tracked = track_modes(selected, options=TrackingOptions())
    assert len(tracked) == 40 and tracked.attrs["harmonic_labels"] == []
    # seen in under half of the voyage's blocks (23-39 of 40, beside a mode at 5.0 Hz seen
    # in all), the same line is what its 8 checked rows show: a harmonic
    rows = [(b, 5.0, SHAPE_FORCED) for b in range(40)] + [
        (b, 2.9, SHAPE_MODE) for b in range(23, 40)
    ]
    selected = _selected(rows)
    checked = (selected["block"] >= 32).to_numpy()
    line = selected["frequency_hz"].eq(2.9).to_numpy()
    selected["harmonic_checked"] = checked
    selected["harmonic"] = np.where(checked & line, 1.0, np.nan)
    selected["harmonic_frequency_hz"] = np.where(checked & line, 2.88, np.nan)
    tracked = track_modes(selected, options=TrackingOptions())
    assert len(tracked) == 40 and tracked["frequency_hz"].eq(5.0).all()
    assert [h["blocks"] for h in tracked.attrs["harmonic_labels"]] == [17]


def _steady_log_voyage(line_hz_of_speed):
    """12 blocks at 5..10 kn, the shaft speed logged steady at 100 rpm (0.2 rpm noise, 0.1
    rpm resolution), the speed logged as it is; a mode at 8.21 Hz (within 2 % of the blade
    pass of 5 blades at 100 rpm, 8.33 Hz) and the lines *line_hz_of_speed* (frequency of
    the block's speed [Hz], shape) in every block."""
    speeds = np.linspace(5.0, 10.0, 12)
    rows = []
    for k, v in enumerate(speeds):
        rows.append((k, 8.21, SHAPE_MODE))
        rows += [(k, line(v), shape) for line, shape in line_hz_of_speed]
    rng = np.random.default_rng(0)
    log = _log(
        lambda t: np.round(100.0 + 0.2 * rng.standard_normal(t.shape), 1),
        12 * 1200,
        lambda t: np.repeat(speeds, 1200)[t],
    )
    return _selected(rows), log


def test_a_frozen_shaft_log_is_not_used_when_the_lines_follow_the_speed():
    # the shaft turns at 0.3 Hz/kn x speed (orders 1 and 2 sweep 1.5-3 and 3-6 Hz), the
    # log repeats 100 rpm. Before: the mode at 8.21 Hz was marked as the blade pass in
    # all 12 blocks (tracking dropped it) and the two swept lines were kept as modes.
    forced2 = np.array([0.2, 1.0, 0.4, -0.5, 0.3, 0.1])
    selected, log = _steady_log_voyage(
        [(lambda v: 0.3 * v, SHAPE_FORCED), (lambda v: 0.6 * v, forced2)]
    )
    marker = HarmonicMarker(log, HarmonicOptions(blades=5))
    marks = marker.mark_selected(selected)
    assert marker.method == "speed"
    mode = marks["frequency_hz"] == 8.21
    assert marks.loc[~mode, "harmonic"].eq(0.0).all()  # the 24 rows of the swept lines
    # the mode is marked only where an order's ratio (k x 0.3 Hz/kn, k = 1, 2, 3, 5, 10)
    # puts it on the mode: 8.21 Hz / v within 3 % of 1.5 (5.45 kn) or 0.9 Hz/kn (9.09 kn)
    speeds = np.linspace(5.0, 10.0, 12)
    ratio = 8.21 / speeds / 0.3
    crossed = (np.abs(np.log(ratio[:, None] / np.array([1, 2, 3, 5, 10]))) <= 0.03).any(axis=1)
    assert np.flatnonzero(crossed).tolist() == [1, 9]
    np.testing.assert_array_equal(marks.loc[mode, "harmonic"].notna().to_numpy(), crossed)
    assert marker.shaft["shaft_rpm"].isna().all()
    # of the 24 swept rows, 21 at no order of 100 rpm (1.667, 3.333, 5 Hz, within 2 %:
    # order 1 at 5.45 kn, order 2 at 5.45 and 8.18 kn are); the mode at the blade pass in
    # the 10 blocks where it does not follow the speed
    assert marker.unmarked() == [
        "ship log: shaft_rpm: the logged shaft speed stays at 100 rpm while the speed spans "
        "5.5-9.5 kn, and 21 selected modes follow the speed at none of its orders (10 sit at "
        "its orders only): the column is not used, harmonics marked from the speed"
    ]
    tracked = track_modes(marks, options=TrackingOptions())
    assert tracked.groupby("mode")["frequency_hz"].mean().round(2).tolist() == [8.21]
    assert len(tracked) == 12


def test_a_steady_shaft_of_a_controllable_pitch_propeller_is_still_used():
    # the same voyage with the shaft truly at 100 rpm (a controllable-pitch propeller: the
    # speed 5-10 kn set by the pitch): order 1 stays at 1.667 Hz and order 2 at 3.333 Hz
    # in every block. No line follows the speed, so the logged shaft speed marks them
    # (and, as nothing tells them apart, the mode on the blade pass).
    selected, log = _steady_log_voyage(
        [(lambda v: 100 / 60, SHAPE_FORCED), (lambda v: 200 / 60, SHAPE_FORCED)]
    )
    marker = HarmonicMarker(log, HarmonicOptions(blades=5))
    marks = marker.mark_selected(selected)
    assert marker.method == "shaft speed" and marker.shaft_log_note is None
    assert marks["harmonic"].tolist() == [5.0, 1.0, 2.0] * 12
    assert marker.shaft["shaft_rpm"].to_numpy() == pytest.approx(100.0, abs=0.1)
    assert marker.unmarked() == []


def test_cli_a_frozen_shaft_log_keeps_the_mode_on_its_blade_pass(tmp_path, capsys):
    # the demo voyage (seed 0, 3 h) with its shaft-speed column set to 100.0 rpm in every
    # row. Before: the mode at 8.21 Hz was marked as the blade pass (8.33 Hz) and left
    # out, and the harmonics at 3.03, 2.13 and 10.42 Hz were tracked as modes.
    from workbench.cli import main

    voyage = tmp_path / "voyage"
    assert main(["simulate", "--out", str(voyage), "--hours", "3", "--quiet"]) == 0
    path = voyage / "dship.tsv"
    lines = path.read_text(encoding="utf-8").split("\n")
    header = next(k for k, line in enumerate(lines) if line.startswith("Date/Time"))
    assert lines[header].split("\t")[8] == "Shaft speed [rpm]"
    for k in range(header + 1, len(lines)):
        if lines[k]:
            fields = lines[k].split("\t")
            lines[k] = "\t".join([*fields[:8], "100.0"])
    path.write_text("\n".join(lines), encoding="utf-8")
    out = tmp_path / "identify"
    argv = ["identify", str(voyage / "accelerations"), "--out", str(out), "--band", "2", "12"]
    argv += ["--dship", str(path), "--blades", "5", "--scheduler", "synchronous", "--quiet"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    said = [line for line in captured.err.splitlines() if "shaft_rpm" in line]
    assert len(said) == 1 and "the column is not used" in said[0]
    tracked_csv = tmp_path / "tracked.csv"
    assert main(["track", str(out / "selected.parquet"), "--out", str(tracked_csv)]) == 0
    medians = pd.read_csv(tracked_csv).groupby("mode")["frequency_hz"].median()
    assert len(medians) == 7  # the voyage's 7 modes
    assert ((medians - 8.21).abs() < 0.02).sum() == 1
    for harmonic_hz in (3.03, 2.13, 10.42):
        assert not ((medians - harmonic_hz).abs() < 0.02).any()
