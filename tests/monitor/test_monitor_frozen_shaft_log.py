"""A frozen shaft-speed log (one value repeated while the shaft follows the speed): the
monitor judges it over every block tracked so far and the log read so far, as
``identify --dship`` judges the voyage (:func:`~workbench.sid.harmonics.
shaft_log_against_speed`), so its marks equal identify's on the blocks so far at every
block. Before, the monitor ran the test on its newest blocks only, whose speed never spans
the knot the test asks for: it kept marking from the frozen log, the true mode on the blade
pass as a harmonic in every block and the lines following the speed not at all (on the
frozen-log audit voyage it tracked 3.026, 2.134 and 10.418 Hz as modes and lost the 8.212 Hz
mode). A controllable-pitch propeller's steady shaft is still used, block by block too."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from data_contracts import shape_columns
from workbench.sid.harmonics import HarmonicMarker, HarmonicOptions, mark_harmonics

from .conftest import marked_frame, marking_monitor

CHANNELS = [f"c{j}" for j in range(6)]
START = pd.Timestamp("2024-03-01T00:00:00Z")
SHAPE_MODE = np.array([1.0, 0.8, 0.3, -0.3, -0.8, -1.0])
SHAPE_FORCED = np.array([1.0, 0.6, 0.35, 0.2, 0.1, 0.05])
SHAPE_FORCED_2 = np.array([0.2, 1.0, 0.4, -0.5, 0.3, 0.1])
COLUMNS = ["harmonic", "harmonic_frequency_hz", "harmonic_checked"]
OPTIONS = HarmonicOptions(blades=5)
#: the blocks' speed [kn]: 12 blocks of 20 min from 5 to 10 kn
SPEEDS = np.linspace(5.0, 10.0, 12)


def _voyage(lines):
    """12 blocks of 20 min at SPEEDS, the shaft speed logged steady at 100 rpm (0.2 rpm
    noise, 0.1 rpm resolution) and the speed as it is, 1-s rows; a mode at 8.21 Hz (within
    2 % of the blade pass of 5 blades at 100 rpm, 8.33 Hz) and *lines* (frequency of the
    block's speed [Hz], shape) in every block: the selected modes and the log."""
    rows = []
    for block, speed in enumerate(SPEEDS):
        rows.append((block, 8.21, SHAPE_MODE))
        rows += [(block, line(speed), shape) for line, shape in lines]
    selected = pd.DataFrame(
        {
            "block": [b for b, _, _ in rows],
            "block_start": [START + pd.Timedelta(minutes=20 * b) for b, _, _ in rows],
            "block_end": [START + pd.Timedelta(minutes=20 * b + 20) for b, _, _ in rows],
            "frequency_hz": [f for _, f, _ in rows],
            "damping_ratio": 0.01,
        }
    )
    shapes = np.array([s / np.linalg.norm(s) for _, _, s in rows])
    names = shape_columns(CHANNELS)
    for j, (re, im) in enumerate(zip(names[:6], names[6:], strict=True)):
        selected[re] = shapes[:, j]
        selected[im] = 0.0
    seconds = np.arange(12 * 1200)
    rpm = np.round(100.0 + 0.2 * np.random.default_rng(0).standard_normal(seconds.shape), 1)
    log = pd.DataFrame(
        {
            "time": START + pd.to_timedelta(seconds, unit="s"),
            "shaft_rpm": rpm,
            "speed_kn": np.repeat(SPEEDS, 1200),
        }
    )
    return selected, log


def _block_by_block(selected, log):
    """The monitor's marks fed block by block, the ship log half a block behind the newest
    block (its marks from the log so far, then again once the log covers it), each step's
    marks against identify's on the blocks so far with the log so far: the monitor and
    the step at which it said the log is not used (None: never)."""
    frame = selected.drop(columns=COLUMNS, errors="ignore")
    monitor = marking_monitor(log, OPTIONS)
    said_at = None
    for block in range(12):
        so_far = frame[frame["block"] <= block]
        now = START + pd.Timedelta(minutes=20 * block + 10)
        grown = log[log["time"] < now].reset_index(drop=True)
        monitor._read_log = lambda grown=grown: grown
        marked = marked_frame(monitor, so_far)
        batch = mark_harmonics(so_far, so_far.iloc[:0], grown, OPTIONS).selected
        pd.testing.assert_frame_equal(marked[COLUMNS], batch[COLUMNS], check_names=False)
        if monitor.messages and said_at is None:
            said_at = block
            # the verdict identify gives the blocks so far, said by the monitor
            marker = HarmonicMarker(grown, OPTIONS)
            marker.mark_selected(so_far)
            assert monitor.messages[0].startswith(f"ship log: {marker.shaft_log_note}; ")
    monitor._read_log = lambda: log
    marked = marked_frame(monitor, frame)
    return monitor, marked, said_at


def test_a_frozen_log_is_judged_over_the_blocks_so_far_as_identify_judges_them():
    # the shaft turns at 0.3 Hz/kn x speed (orders 1 and 2 sweep 1.5-3 and 3-6 Hz), the log
    # repeats 100 rpm
    selected, log = _voyage(
        [(lambda v: 0.3 * v, SHAPE_FORCED), (lambda v: 0.6 * v, SHAPE_FORCED_2)]
    )
    monitor, marked, said_at = _block_by_block(selected, log)
    whole = HarmonicMarker(log, OPTIONS)
    expected = whole.mark_selected(selected.copy())
    assert whole.method == "speed"
    pd.testing.assert_frame_equal(marked[COLUMNS], expected[COLUMNS], check_names=False)
    # the 24 rows of the swept lines marked from the speed; the mode only where an order's
    # ratio puts it on the mode (5.45 and 9.09 kn: blocks 1 and 9), not in all 12 blocks
    # at the blade pass of the frozen 100 rpm (main: harmonic 5.0 in every block)
    mode = marked["frequency_hz"] == 8.21
    assert marked.loc[~mode, "harmonic"].eq(0.0).all()
    assert marked.loc[mode & marked["harmonic"].notna(), "block"].tolist() == [1, 9]
    # the verdict turns once the speed spans a knot with the lines' rows counted: said
    # once, at block 4 (the speed 5-6.8 kn), naming the blocks whose marks are given again
    assert said_at == 4
    assert monitor.messages == [
        "ship log: shaft_rpm: the logged shaft speed stays at 100 rpm while the speed spans "
        "5.2-6.6 kn, and 8 selected modes follow the speed at none of its orders (4 sit at "
        "its orders only): the column is not used, harmonics marked from the speed; the "
        "harmonics of blocks 0-4, marked from the logged shaft speed before, are marked "
        "again from the speed"
    ]
    assert monitor._shaft_log_note.startswith("shaft_rpm: the logged shaft speed stays at 100")


def test_a_steady_shaft_of_a_controllable_pitch_propeller_is_still_used_block_by_block():
    # the shaft truly at 100 rpm while the pitch sets 5-10 kn: order 1 at 1.667 Hz and
    # order 2 at 3.333 Hz in every block, no line following the speed
    selected, log = _voyage(
        [(lambda v: 100 / 60, SHAPE_FORCED), (lambda v: 200 / 60, SHAPE_FORCED)]
    )
    monitor, marked, said_at = _block_by_block(selected, log)
    assert said_at is None and monitor._shaft_log_note is None
    assert marked["harmonic"].tolist() == [5.0, 1.0, 2.0] * 12
    np.testing.assert_allclose(
        marked["harmonic_frequency_hz"].to_numpy().reshape(12, 3),
        np.outer(np.ones(12), [5, 1, 2]) * 100 / 60,
        rtol=2e-3,
    )


@pytest.mark.parametrize("blocks", [range(12), [*range(8), 8, 9, 10, 11]])
def test_the_verdict_on_the_whole_voyage_at_once_is_identify_s(blocks):
    # a restart replays the stored blocks at once: the same verdict and marks as identify
    selected, log = _voyage(
        [(lambda v: 0.3 * v, SHAPE_FORCED), (lambda v: 0.6 * v, SHAPE_FORCED_2)]
    )
    monitor = marking_monitor(log, OPTIONS)
    frame = selected[selected["block"].isin(list(blocks))]
    marked = marked_frame(monitor, frame)
    expected = HarmonicMarker(log, OPTIONS).mark_selected(frame.copy())
    pd.testing.assert_frame_equal(marked[COLUMNS], expected[COLUMNS], check_names=False)
    assert len(monitor.messages) == 1 and "the column is not used" in monitor.messages[0]
    assert "marked again" not in monitor.messages[0]  # nothing was marked before


def test_a_verdict_that_turns_back_marks_every_block_again_from_the_log_and_says_so():
    # the lines follow the speed in blocks 0-5 (the log judged frozen at block 4); from
    # block 6 on the shaft turns at the logged 100 rpm (orders 1, 2 and 3 at 1.667, 3.333
    # and 5 Hz): by block 7 more modes sit at its orders than follow the speed, and the
    # log is used again for every block, as identify uses it on blocks 0-7
    selected, log = _voyage(
        [(lambda v: 0.3 * v, SHAPE_FORCED), (lambda v: 0.6 * v, SHAPE_FORCED_2)]
    )
    late = (selected["block"] >= 6) & (selected["frequency_hz"] != 8.21)
    selected.loc[late, "frequency_hz"] = np.tile([100 / 60, 200 / 60], 6)
    third = selected[late].assign(frequency_hz=300 / 60)
    selected = pd.concat([selected, third]).sort_values(["block", "frequency_hz"], kind="stable")
    monitor, marked, said_at = _block_by_block(selected.reset_index(drop=True), log)
    assert said_at == 4 and len(monitor.messages) == 2
    assert monitor.messages[1] == (
        "ship log: shaft_rpm: the logged shaft speed is used again (with the blocks tracked "
        "so far it is no longer contradicted by the speed); the harmonics of blocks 0-7 are "
        "marked again from it"
    )
    assert monitor._shaft_log_note is None
    expected = HarmonicMarker(log, OPTIONS).mark_selected(selected.reset_index(drop=True))
    pd.testing.assert_frame_equal(marked[COLUMNS], expected[COLUMNS], check_names=False)
    # blocks 6-11: orders 1, 2, 3 (twice) and the mode on the blade pass of 100 rpm
    late = marked[marked["block"] >= 6]
    assert late["harmonic"].tolist() == [1.0, 2.0, 3.0, 3.0, 5.0] * 6
