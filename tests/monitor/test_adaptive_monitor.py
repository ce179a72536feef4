"""``workbench monitor --block-minutes auto``: blocks of varying length decided live as
``identify --block-minutes auto`` decides them on the whole voyage.

The reference is the batch run a user makes over the finished folder: ``identify
--block-minutes auto --dship`` + ``track`` + ``forecast``. The test voyage (conftest: the
demo simulator, 1.5 h, 6 channels) gives 14 blocks of 5 min and 4 of 15 min: speed changes
of more than 1 kn and excitation ranges above 3 dB keep most blocks short.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import MODAL, read_table, recorded_grid
from workbench.cli import parse_arguments
from workbench.cli.monitoring import prepare_monitor

from .conftest import FORECAST, IDENTIFY, MONITOR_FAST, ShipLog, cli, file_end, land

AUTO = ["--block-minutes", "auto"]


def _store(state: Path, kind: str) -> pd.DataFrame:
    files = sorted((state / "store" / kind).glob("day=*/*.parquet"))
    frame = pd.concat([pd.read_parquet(p) for p in files], ignore_index=True)
    return frame.drop(columns=["day"], errors="ignore").sort_values("block", kind="stable")


@pytest.fixture(scope="module")
def batch_auto(voyage, tmp_path_factory):
    """identify --block-minutes auto + track + forecast over the complete folder."""
    out = tmp_path_factory.mktemp("monitor_batch_auto")
    common = ["--scheduler", "synchronous", "--quiet"]
    assert cli(
        "identify", voyage / "accelerations", "--out", out / "id", *IDENTIFY, *AUTO,
        "--dship", voyage / "dship.tsv", *common,
    ) == 0  # fmt: skip
    assert cli("track", out / "id" / "selected.parquet", "--out", out / "tracked.parquet") == 0
    assert cli(
        "forecast", "--modal", out / "tracked.parquet", "--dship", voyage / "dship.tsv",
        *FORECAST, "--out", out / "forecast.parquet", "--quiet",
    ) == 0  # fmt: skip
    return {
        "blocks": pd.read_csv(out / "id" / "blocks.csv"),
        "selected": pd.read_parquet(out / "id" / "selected.parquet"),
        "excitation": pd.read_csv(out / "id" / "excitation.csv"),
        "tracked": pd.read_parquet(out / "tracked.parquet"),
        "forecast": pd.read_parquet(out / "forecast.parquet"),
    }


def test_a_block_decided_on_its_span_is_decided_as_on_the_whole_voyage():
    """What the monitor relies on: the plan of a prefix of the half-steps (or of a window
    from a decision span's first half-step) gives every block whose decision span it
    holds the row the whole voyage's plan gives it."""
    from workbench.identification.adaptive import (
        AdaptiveBlockOptions,
        decision_span,
        last_block,
        plan_block_lengths,
    )

    options = AdaptiveBlockOptions()
    assert decision_span(0, options) == (0, 8) and decision_span(5, options) == (4, 18)
    assert last_block(36, options) == 17 and last_block(1, options) == -1
    rng = np.random.default_rng(7)
    n = 120  # 5 h of half-steps: calm and ice, speed steps, a gap
    t0 = pd.Timestamp("2024-03-01T00:00:00Z")
    start = t0 + pd.Timedelta(seconds=150) * np.arange(n)
    power_db = np.where(np.arange(n) < 60, 0.4 * rng.random(n), 6.0 * rng.standard_normal(n))
    power = 1e-5 * 10 ** (power_db / 10)
    power[[70, 71]] = np.nan
    speed = np.where(np.arange(n) % 40 < 20, 10.0, 4.0) + 0.1 * rng.standard_normal(n)
    half_steps = pd.DataFrame(
        {"start": start, "end": start + pd.Timedelta(seconds=150), "power": power}
    )
    half_steps["speed_kn"] = speed
    whole = plan_block_lengths(half_steps, t0).set_index("block")
    assert set(whole["block_length_s"]) == {300.0, 900.0, 1500.0, 2100.0}
    for prefix in range(10, n, 7):
        part = plan_block_lengths(half_steps.iloc[:prefix], t0).set_index("block")
        held = [b for b in part.index if decision_span(b, options)[1] <= prefix]
        assert held, prefix
        spans_in = [b for b in range(last_block(prefix, options) + 1)
                    if decision_span(b, options)[1] <= prefix]  # fmt: skip
        # the same blocks left out (a gap in every span)
        assert [b in part.index for b in spans_in] == [b in whole.index for b in spans_in]
        pd.testing.assert_frame_equal(part.loc[held], whole.loc[held])
        first = decision_span(held[-1], options)[0]
        window = half_steps.iloc[first:prefix].reset_index(drop=True)
        shifted = plan_block_lengths(window, start[first]).set_index("block")
        shifted.index += first // 2
        pd.testing.assert_frame_equal(shifted.loc[[held[-1]]], whole.loc[[held[-1]]])


def _monitor(watch: Path, state: Path, dship: Path, *extra):
    argv = ["monitor", "--watch", watch, "--state", state, "--dship", dship, *AUTO]
    argv += [*IDENTIFY, *FORECAST, *MONITOR_FAST, "--foreground", *extra]
    return prepare_monitor(parse_arguments([str(a) for a in argv]))


def _assert_equals_batch(state: Path, batch: dict, *, forecast: bool = True) -> None:
    """The monitor's lengths, selected modes, tracked table (and forecast) are the batch's."""
    blocks = batch["blocks"]
    # not vacuous: blocks of two lengths, every block identified
    assert sorted(blocks["block_length_s"].value_counts().items()) == [(300.0, 14), (900.0, 4)]
    lengths = _store(state, "lengths")
    assert lengths["block"].tolist() == blocks["block"].tolist() == list(range(18))
    np.testing.assert_array_equal(lengths["block_length_s"], blocks["block_length_s"])
    # the stationarity measures are computed from the same half-steps: to rounding
    for column in ("excitation_range_db", "speed_range_kn"):
        np.testing.assert_allclose(lengths[column], blocks[column], rtol=1e-12, atol=0)
    np.testing.assert_array_equal(
        pd.to_datetime(lengths["block_start"], utc=True),
        pd.to_datetime(blocks["block_start"], utc=True),
    )
    keys = ["block", "model_order", "frequency_hz"]
    selected = _store(state, "selected").sort_values(keys).reset_index(drop=True)
    expected = batch["selected"].sort_values(keys).reset_index(drop=True)
    assert len(selected) == len(expected) > 2 * len(blocks)
    np.testing.assert_array_equal(selected["block"], expected["block"])
    np.testing.assert_allclose(selected["frequency_hz"], expected["frequency_hz"], rtol=1e-12)
    np.testing.assert_allclose(selected["block_length_s"], expected["block_length_s"])
    tracked = pd.read_parquet(state / "tracked.parquet")
    pd.testing.assert_frame_equal(tracked, batch["tracked"])
    spans = (tracked["block_end"] - tracked["block_start"]).dt.total_seconds()
    np.testing.assert_array_equal(spans, tracked["block_length_s"])
    assert set(spans) == {300.0, 900.0}
    grid = recorded_grid(read_table(state / "tracked.parquet", MODAL))
    assert grid is not None and grid["varying_length"] is True and grid["step_s"] == 300.0
    if forecast:
        got = pd.read_parquet(state / "forecast.parquet")
        assert got["kalman_frequency_hz"].notna().sum() >= 10
        assert got["log_coverage"].between(0, 1).all()  # the ship log's share of each block
        pd.testing.assert_frame_equal(got, batch["forecast"])


def test_once_equals_identify_auto_track_and_forecast(voyage, batch_auto, tmp_path, capsys):
    """``monitor --once --block-minutes auto`` over the finished folder: the batch tables,
    and excitation.csv the batch's half-steps."""
    state = tmp_path / "state"
    assert cli(
        "monitor", "--watch", voyage / "accelerations", "--state", state,
        "--dship", voyage / "dship.tsv", *AUTO, *IDENTIFY, *FORECAST, *MONITOR_FAST, "--once",
    ) == 0  # fmt: skip
    printed = capsys.readouterr().out
    assert "18 block(s) decided, tracked up to block 17" in printed
    # the last blocks' longer spans reach past the data: said, as the batch decides them (in
    # the run's notes; the terminal shows the last 10 of them)
    assert "decided at the end of the data present" in (state / "notes.txt").read_text()
    _assert_equals_batch(state, batch_auto)
    excitation = pd.read_csv(state / "excitation.csv")
    assert len(excitation) == len(batch_auto["excitation"]) == 36  # 1.5 h of 2.5-min steps
    for column in ("power", "speed_kn"):
        np.testing.assert_allclose(
            excitation[column], batch_auto["excitation"][column], rtol=1e-12, equal_nan=True
        )


def test_live_blocks_wait_for_their_longest_span_and_equal_batch(voyage, batch_auto, tmp_path):
    """Files and ship log landing one by one: a block is decided only once the data up to
    its longest span's end (17.5 min past its centre) has landed; the run ends equal to
    the batch run, forecast included (resumed update by update)."""
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    log = ShipLog(voyage / "dship.tsv", tmp_path / "dship.tsv")
    files = sorted((voyage / "accelerations").glob("*.npz"))
    monitor = _monitor(watch, state, log.target, "--settle", "0")
    try:
        for count, path in enumerate(files, start=1):
            land(path, watch)
            log.until(file_end(path))
            monitor.step()
            # block k is centred at 2.5 + 5k min; its 35-min span ends at 20 + 5k min; the
            # ship log has no rows from 00:49 to 00:58 (a logger outage): the blocks reaching
            # past 00:49 wait for it within the late window (15 min), so until it resumes
            landed_min = 5 * count
            log_end_min = 49 if landed_min < 60 else landed_min
            decidable = {k for k in range(18) if 20 + 5 * k <= min(landed_min, log_end_min)}
            assert set(monitor._lengths) == decidable, count
            assert monitor.done <= decidable
        assert max(monitor.done) == 14  # blocks 15-17 reach past the data: waiting
        log.until(None)
        monitor.step(flush=True)  # the input has ended
        assert len(monitor.done) == 18
    finally:
        monitor.close()
    _assert_equals_batch(state, batch_auto)
    status = json.loads((state / "status.json").read_text(encoding="utf-8"))
    assert status["blocks_done"] == 18 and status["last_block"] == 17


def test_ship_log_behind_is_waited_for_within_the_late_window(voyage, batch_auto, tmp_path):
    """A ship log that stays behind holds the lengths of the blocks whose spans it does not
    cover until data --late seconds newer has landed; then they are decided without its
    speed, said in the messages; never a hang."""
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    log = ShipLog(voyage / "dship.tsv", tmp_path / "dship.tsv")
    files = sorted((voyage / "accelerations").glob("*.npz"))
    t0 = pd.Timestamp("2024-03-01T00:00:00Z")
    log.until(t0 + pd.Timedelta(minutes=30))
    monitor = _monitor(watch, state, log.target, "--settle", "0", "--late", "1800")
    try:
        for path in files:
            land(path, watch)
        monitor.step()
        # horizons up to 30 min: the log covers them (blocks 0-2); up to 90 - 30 = 60 min:
        # the log's 30-min late window has passed (blocks 3-8); the rest wait for the log
        assert sorted(monitor._lengths) == list(range(9))
        assert any(
            "block lengths of blocks 3-8 decided without the ship log's speed" in m
            for m in monitor.messages
        )
        log.until(None)
        monitor.step(flush=True)
    finally:
        monitor.close()
    blocks = batch_auto["blocks"].set_index("block")
    lengths = _store(state, "lengths").set_index("block")
    assert lengths.index.tolist() == list(range(18))
    # blocks 0-2 and 9-17 read the log's speed as the batch run does: its decisions
    covered = [*range(3), *range(9, 18)]
    for column in ("block_length_s", "speed_range_kn"):
        np.testing.assert_allclose(
            lengths.loc[covered, column], blocks.loc[covered, column], rtol=1e-12
        )


def test_restart_after_kill_loses_and_repeats_nothing(voyage, batch_auto, tmp_path, capsys):
    """kill -9 mid-run, then ``--once``: the blocks stored before the kill are kept (their
    lengths too), the half-steps measured are read back, the tables equal the batch's."""
    import signal
    import subprocess
    import sys

    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    files = sorted((voyage / "accelerations").glob("*.npz"))
    argv = ["monitor", "--watch", watch, "--state", state, "--dship", voyage / "dship.tsv"]
    argv += [*AUTO, *IDENTIFY, *FORECAST, *MONITOR_FAST, "--foreground"]
    code = "import sys; from workbench.cli import main; sys.exit(main(sys.argv[1:]))"
    process = subprocess.Popen([sys.executable, "-c", code, *map(str, argv)])
    try:
        for path in files[:10]:  # blocks 0-6 decidable (spans to 50 min)
            land(path, watch)
            time.sleep(0.05)
        rows = state / "data_health.parquet"
        deadline = time.monotonic() + 300
        while not (rows.exists() and len(pd.read_parquet(rows)) >= 3):
            assert time.monotonic() < deadline, "the monitor decided no block"
            time.sleep(0.05)
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    before = pd.read_parquet(state / "data_health.parquet")
    assert 3 <= len(before) <= 7
    measured = pd.read_csv(state / "excitation.csv")
    assert len(measured) >= 20  # the half-steps of the 50 min landed
    for path in files[10:]:
        land(path, watch)
    assert cli(
        "monitor", "--watch", watch, "--state", state, "--dship", voyage / "dship.tsv",
        *AUTO, *IDENTIFY, *FORECAST, *MONITOR_FAST, "--once",
    ) == 0  # fmt: skip
    _assert_equals_batch(state, batch_auto)
    health = pd.read_parquet(state / "data_health.parquet")
    assert health["block"].tolist() == list(range(18))
    kept = health.set_index("block").loc[before["block"], "identified_at"]
    assert (kept.to_numpy() == before["identified_at"].to_numpy()).all()
    assert _store(state, "lengths")["block"].is_unique
    # the store remembers the adaptive rule: fixed blocks are not resumed from it (with
    # the state folder's ship log: without it the restart is refused before, exit 2)
    capsys.readouterr()
    assert cli(
        "monitor", "--watch", watch, "--state", state, "--dship", voyage / "dship.tsv",
        *IDENTIFY, *MONITOR_FAST, "--once",
    ) == 1  # fmt: skip
    err = capsys.readouterr().err
    assert "store was made with other parameters (adaptive, length_s)" in err
    assert "use another --state folder" in err and "Traceback" not in err
    # the half-steps measured before the kill were read back: the file is the batch run's
    excitation = pd.read_csv(state / "excitation.csv")
    np.testing.assert_allclose(
        excitation["power"], batch_auto["excitation"]["power"], rtol=1e-12, atol=0
    )


def test_decimated_files_fed_one_by_one_equal_batch(tmp_path):
    """128-Hz files decimated to 64 Hz (each file conditioned once per length's grid: a
    conditioned file is cut on its grid, so the lengths do not share it), fed one by one:
    the tables of identify --block-minutes auto + track."""
    from .conftest import write_voyage

    voyage = write_voyage(tmp_path / "v128", rate_hz=128.0, seed=4, hours=1.0)
    out = tmp_path / "batch"
    assert cli(
        "identify", voyage / "accelerations", "--out", out / "id", *IDENTIFY, *AUTO,
        "--dship", voyage / "dship.tsv", "--scheduler", "synchronous", "--quiet",
    ) == 0  # fmt: skip
    assert cli("track", out / "id" / "selected.parquet", "--out", out / "tracked.parquet") == 0
    blocks = pd.read_csv(out / "id" / "blocks.csv")
    assert sorted(blocks["block_length_s"].value_counts().items()) == [(300.0, 11), (900.0, 1)]
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    monitor = _monitor(watch, state, voyage / "dship.tsv", "--settle", "0")
    try:
        for path in sorted((voyage / "accelerations").glob("*.npz")):
            land(path, watch)
            monitor.step()
        monitor.step(flush=True)
    finally:
        monitor.close()
    pd.testing.assert_frame_equal(
        pd.read_parquet(state / "tracked.parquet"), pd.read_parquet(out / "tracked.parquet")
    )
    lengths = _store(state, "lengths")
    np.testing.assert_array_equal(lengths["block_length_s"], blocks["block_length_s"])
    assert monitor.conditioned_files[0] >= 12  # every file once on the 5-min grid at least


def test_states_split_blocks_as_identify_cases_does(voyage, tmp_path):
    """--cases: no block straddles a change of state, in the monitor as in identify."""
    cases = tmp_path / "cases.csv"
    cases.write_text(
        "case,start,end\n"
        "transit,2024-03-01T00:00:00Z,2024-03-01T00:40:00Z\n"
        "station,2024-03-01T00:40:00Z,2024-03-01T02:00:00Z\n"
    )
    out, state = tmp_path / "batch", tmp_path / "state"
    assert cli(
        "identify", voyage / "accelerations", "--out", out, *IDENTIFY, *AUTO, "--cases", cases,
        "--dship", voyage / "dship.tsv", "--scheduler", "synchronous", "--quiet",
    ) == 0  # fmt: skip
    assert cli(
        "monitor", "--watch", voyage / "accelerations", "--state", state, "--dship",
        voyage / "dship.tsv", *AUTO, "--cases", cases, *IDENTIFY, *MONITOR_FAST, "--once",
    ) == 0  # fmt: skip
    blocks = pd.read_csv(out / "blocks.csv", parse_dates=["block_start"])
    lengths = _store(state, "lengths")
    assert lengths["block"].tolist() == blocks["block"].tolist()
    np.testing.assert_array_equal(lengths["block_length_s"], blocks["block_length_s"])
    change = pd.Timestamp("2024-03-01T00:40:00Z")
    start = pd.to_datetime(lengths["block_start"], utc=True)
    end = pd.to_datetime(lengths["block_end"], utc=True)
    assert not ((start < change) & (end > change)).any()
    assert (lengths["block_length_s"] > 300).any()  # not vacuous: longer blocks elsewhere


@pytest.mark.parametrize(
    ("extra", "code", "needle"),
    [
        (["--cases", "cases.csv"], 2, "--cases is used with --block-minutes auto only"),
        ([*AUTO, "--cases", "missing.csv"], 2, "--cases missing.csv: no such file"),
        ([*AUTO, "--step-minutes", "1"], 2, "--block-minutes auto with --step-minutes"),
        ([*AUTO, "--cases", "bad.csv"], 1, "bad.csv: cases table lacks column(s) end"),
    ],
)
def test_bad_adaptive_flags(extra, code, needle, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "watch").mkdir()
    Path("cases.csv").write_text("case,start,end\nice,2024-03-01,2024-03-02\n")
    Path("bad.csv").write_text("case,start\nice,2024-03-01\n")
    argv = ["monitor", "--watch", "watch", "--state", "s", "--once", *extra]
    assert cli(*argv) == code
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
