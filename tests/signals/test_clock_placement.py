"""place_files over a day of 5-min files at 2048 Hz (headers only): sample-clock drift and
stamp jitter together keep one record, a real gap stays a gap.

The stamps are drawn as a recorder writes them: file k starts k * 300 s / (1 + ppm) after
the first (its sample clock ppm fast) plus a jitter uniform in +-J. Before, any drift
broke the record within the hour (an "overlap" error: 20 ppm passes 50 ms after 9 files).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.signals.block_plan import FileInfo, FileOverlapError, clock_runs, place_files

RATE_HZ = 2048.0
N_SAMPLES = int(300 * RATE_HZ)
T0 = pd.Timestamp("2026-03-01T00:00:00Z")


def _headers(ppm: float, jitter_ms: float, seed: int, n_files: int = 288) -> list[FileInfo]:
    rng = np.random.default_rng(seed)
    stamps = np.arange(n_files) * 300.0 / (1 + ppm * 1e-6)
    stamps += rng.uniform(-jitter_ms, jitter_ms, n_files) / 1e3
    return [
        FileInfo(
            Path(f"acc_{k:03d}.npz"),
            T0 + pd.Timedelta(seconds=float(s)),
            RATE_HZ,
            N_SAMPLES,
            ("a",),
        )
        for k, s in enumerate(stamps)
    ]


def _abut(placed) -> bool:
    return all(b.start_time == a.end_time for a, b in zip(placed, placed[1:], strict=False))


@pytest.mark.parametrize("ppm", [-100.0, -20.0, 20.0, 100.0])
def test_drift_with_10_ms_jitter_is_one_record_with_its_rate(ppm):
    for seed in range(10):
        placed = place_files(_headers(ppm, 10.0, seed))
        assert _abut(placed)  # one record: every file at its predecessor's end
        (run,) = clock_runs(placed)
        # the least-squares rate of 288 stamps over a day, jitter +-10 ms: its standard
        # error 5.8 ms / 86400 s * sqrt(12 / 288) = 0.014 ppm
        assert run.rate_offset * 1e6 == pytest.approx(ppm, abs=0.1)
        assert run.drifting
        assert 0.009 < run.jitter_s <= 0.012  # the drawn 10 ms, less or more the line's error
        # the sample count walks from the stamps by ppm of the day: 20 ppm, 1.7 s
        walk_s = abs(placed[-1].clock_shift_s)
        assert walk_s == pytest.approx(287 * 300 * abs(ppm) * 1e-6, abs=0.03)


def test_jitter_alone_never_breaks_the_record():
    """Up to +-25 ms (a stamp may miss its predecessor's by 50 ms): as before."""
    for seed in range(20):
        placed = place_files(_headers(0.0, 25.0, seed))
        assert _abut(placed)
        assert not clock_runs(placed)[0].drifting
        assert max(abs(i.clock_shift_s) for i in placed) <= 0.05


def test_a_gap_shorter_than_the_walk_is_a_gap_and_the_record_goes_on():
    """20 ppm fast: after 48 files the sample count lies 288 ms past the stamps; 250 ms of
    data lost there is still a gap, of its own length, and the files after it one record."""
    infos = _headers(20.0, 0.0, 0, n_files=96)
    infos[48:] = [
        FileInfo(i.path, i.start_time + pd.Timedelta(milliseconds=250), RATE_HZ, N_SAMPLES, ("a",))
        for i in infos[48:]
    ]
    placed = place_files(infos)  # main: acc_009.npz "overlapping or duplicate files"
    gap_s = (placed[48].start_time - placed[47].end_time).total_seconds()
    # on the sample count: the samples a clock 20 ppm fast counts in 250 ms
    assert gap_s == pytest.approx(0.250 * (1 + 20e-6), abs=1e-6)
    assert _abut(placed[:48]) and _abut(placed[48:])
    assert [len(run.files) for run in clock_runs(placed)] == [48, 48]


@pytest.mark.parametrize("ppm", [-40.0, 40.0])
def test_a_lost_file_keeps_the_record_on_its_sample_count(ppm):
    """File 24 of 48 lost (10 ms jitter): the files after it start where the recorder's
    sample count puts them, to within their stamps' jitter and the line's error (2 ms
    here), not at their stamps, 24 * 300 s * 40 ppm = 288 ms away from it (main: 288 ms +-
    10 ms), and their record ends where the voyage's sample count does."""
    for seed in range(5):
        infos = _headers(ppm, 10.0, seed, n_files=48)
        placed = place_files(infos[:24] + infos[25:])
        assert [len(run.files) for run in clock_runs(placed)] == [24, 23]
        counted = placed[0].start_time + pd.Timedelta(seconds=25 * 300.0)
        assert abs((placed[24].start_time - counted).total_seconds()) < 0.012
        end = placed[0].start_time + pd.Timedelta(seconds=48 * 300.0)
        assert abs((placed[-1].end_time - end).total_seconds()) < 0.012


@pytest.mark.parametrize("ppm", [-40.0, 40.0])
def test_a_second_lost_file_soon_after_the_first_keeps_the_sample_count(ppm):
    """Files 24 and 27 of 48 lost (10 ms jitter): the two files between the gaps cannot
    tell a drift from jitter, but the record's clock carries its time over the second gap
    too, so the files after it start where the sample count puts them (main: at their
    stamps, 28 * 300 s * 40 ppm = 336 ms away), to within the lines' error there (up to
    10 ms here; the rule: twice its standard error within half the jitter). File 27
    landing late (the monitor) then moves them by the two lines' errors only (up to 15 ms
    here, within the jitter), not by that walk (main: 336 ms, more than the 0.1 s by which
    the monitor's store tells other data: it refused the late file)."""
    for seed in range(5):
        infos = _headers(ppm, 10.0, seed, n_files=48)
        placed = place_files(infos[:24] + infos[25:27] + infos[28:])
        assert [len(run.files) for run in clock_runs(placed)] == [24, 2, 20]
        counted = placed[0].start_time + pd.Timedelta(seconds=28 * 300.0)
        assert abs((placed[26].start_time - counted).total_seconds()) < 0.025  # main: 0.336
        filled = place_files(infos[:24] + infos[25:])  # file 27 landed
        moved_s = (filled[27].start_time - placed[26].start_time).total_seconds()
        assert abs(moved_s) < 0.050  # main: 0.336


def test_after_a_long_gap_a_record_starts_at_its_stamp():
    """Two days after a 2-h record whose stamps scatter by up to 10 ms about their line:
    the line's time there is uncertain by about 0.1 s (its rate by 0.6 ppm), more than the
    jitter, so the record after the gap starts at its stamp, as every record did before."""
    infos = _headers(40.0, 10.0, 0, n_files=48)
    late = [
        FileInfo(i.path, i.start_time + pd.Timedelta(days=2), RATE_HZ, N_SAMPLES, ("a",))
        for i in infos[24:]
    ]
    placed = place_files(infos[:24] + late)
    assert placed[24].start_time == late[0].start_time
    assert placed[24].clock_shift_s == 0.0


def test_an_overlap_in_a_drifting_record_names_the_file():
    infos = _headers(20.0, 5.0, 0, n_files=96)
    infos[60:] = [
        FileInfo(i.path, i.start_time - pd.Timedelta(milliseconds=200), RATE_HZ, N_SAMPLES, ("a",))
        for i in infos[60:]
    ]
    with pytest.raises(FileOverlapError) as raised:
        place_files(infos)
    assert raised.value.info.name == "acc_060.npz"
    assert raised.value.previous.name == "acc_059.npz"
    seconds = float(str(raised.value).split("starts ")[1].split(" s before")[0])
    assert seconds == pytest.approx(0.2, abs=0.012)  # 200 ms, less the jitter (5 + 5 ms)


@pytest.mark.parametrize("ppm, gap_s", [(20.0, 0.0), (-60.0, 2.0), (100.0, -30.0)])
def test_a_placement_resumed_file_by_file_equals_the_whole_placement(ppm, gap_s):
    # the monitor places each newly landed file on from the placement of those before it
    # (FilePlacement) instead of placing every file again: the same headers, the same error
    from workbench.monitor.core import Monitor
    from workbench.monitor.taken import TakenFiles
    from workbench.monitor.watcher import LandedFile
    from workbench.signals.block_plan import FilePlacement

    infos = _headers(ppm, 8.0, seed=3, n_files=60)
    infos[30:] = [  # a real gap (or, negative, an overlap) after file 29
        FileInfo(i.path, i.start_time + pd.Timedelta(seconds=gap_s), RATE_HZ, N_SAMPLES, ("a",))
        for i in infos[30:]
    ]
    try:
        whole = place_files(infos)
    except FileOverlapError as error:
        whole = error
    placement = FilePlacement()
    resumed = []
    try:
        for info in infos:
            trial = placement.place(info)  # placing without keeping changes nothing
            assert len(placement.files) == len(resumed)
            kept = placement.add(info)
            assert kept == trial
            resumed.append(kept)
    except FileOverlapError as error:
        assert isinstance(whole, FileOverlapError) and str(error) == str(whole)
        assert len(placement.files) == 30 and error.info.path == infos[30].path
        return
    assert tuple(resumed) == whole
    # the monitor's placed headers, files taken one at a time, equal the whole placement
    monitor = Monitor.__new__(Monitor)
    monitor.files = TakenFiles()
    landed = pd.Timestamp("2026-03-01T06:00:00Z")
    for info in infos:
        monitor.files.add(LandedFile(info, landed, 0, 0))
        monitor._placed()
    assert tuple(f.info for f in monitor._placed()) == whole
    runs = clock_runs(whole)
    assert placement.last_run_drifting == runs[-1].drifting
    assert placement.files[placement.run_start] == runs[-1].files[0]
