"""Every bad input or option gives the right exit code and a one-line message, no traceback.

Table-driven: each case is a command (run in-process through ``workbench.cli.main``), the
expected exit code (0 ok, 1 bad data or file, 2 usage) and a fragment of what it prints.
Usage errors (exit 2) must not be prefixed with an input file's name; no case may print
a traceback, NumPy's ``np.float64(...)`` repr or an unsilenced NumPy warning. The inputs
are small (a 4-h simulated table set without accelerations, a 4-minute 32-Hz voyage), so
the whole table runs in seconds.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.cli import main

from .voyage import CHANNELS, IDENTIFY_ARGS, RATE_HZ, T0, response, write_voyage


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    """Inputs of every case, made once."""
    from workbench.simulate import simulate_voyage

    base = tmp_path_factory.mktemp("cases")
    sim = base / "sim"
    simulate_voyage(sim, seed=0, hours=4, accelerations=False)
    simulate_voyage(base / "other", seed=3, hours=4, accelerations=False)
    write_voyage(base / "voyage", n_files=4)
    _derived_tables(base, sim)
    _derived_accelerations(base)
    return base


def _derived_tables(base: Path, sim: Path) -> None:
    modal = pd.read_csv(sim / "tracked_modal.csv")
    predictors = pd.read_csv(sim / "truth_predictors.csv")
    # predictors of the next day (same block numbers, other times)
    day = predictors.copy()
    for column in ("block_start", "block_end"):
        day[column] = (pd.to_datetime(day[column]) + pd.Timedelta(days=1)).dt.strftime(
            "%Y-%m-%dT%H:%M:%SZ"
        )
    day.to_csv(base / "predictors_next_day.csv", index=False)
    truth = pd.read_csv(sim / "truth_modal.csv")
    for column in ("block_start", "block_end"):
        truth[column] = (pd.to_datetime(truth[column]) + pd.Timedelta(days=1)).dt.strftime(
            "%Y-%m-%dT%H:%M:%SZ"
        )
    truth.to_csv(base / "truth_next_day.csv", index=False)
    # predictors shifted by one block: block k holds the values and times of block k - 1
    shifted = predictors.copy()
    shifted["block"] += 1
    shifted.to_csv(base / "predictors_shifted.csv", index=False)
    # a predictor whose name is matplotlib mathtext
    odd = predictors.rename(columns={"elapsed_hours": "$\\alpha_{x$"})
    odd.to_csv(base / "predictors_mathtext.csv", index=False)
    dead = predictors.copy()
    dead["water_temp_c"] = np.nan  # a sensor dead for the whole voyage
    dead.to_csv(base / "predictors_dead_column.csv", index=False)
    # modal tables: header only; a block number far beyond any time
    modal.iloc[:0].to_csv(base / "modal_header_only.csv", index=False)
    huge = modal.copy()
    huge.loc[0, "block"] = 10**18
    huge.to_csv(base / "modal_block_1e18.csv", index=False)
    modal.to_csv(base / "modal.txt", index=False)
    (base / "modal.bin").write_bytes(np.random.default_rng(0).bytes(3000))
    # ship log: shifted by 30 days (no overlap); a ragged row
    lines = (sim / "dship.tsv").read_text(encoding="utf-8").splitlines(keepends=True)
    head = next(i for i, line in enumerate(lines) if line.startswith("Date/Time"))
    (base / "dship_ragged.tsv").write_text(
        "".join(
            lines[: head + 3] + [lines[head + 3].rstrip("\n") + "\t1\t2\t3\n"] + lines[head + 4 :]
        ),
        encoding="utf-8",
    )
    late = [line.replace("2024-03-", "2024-04-") for line in lines[head + 1 :]]
    (base / "dship_late.tsv").write_text("".join(lines[: head + 1] + late), encoding="utf-8")
    # cases: one named "all"
    cases = pd.read_csv(sim / "cases.csv")
    cases.loc[0, "case"] = "all"
    cases.to_csv(base / "cases_all.csv", index=False)
    # a forecast and a forecast whose mode 1 has no SSI estimate when forecasting
    assert (
        main(
            [
                "forecast",
                "--modal",
                str(sim / "tracked_modal.csv"),
                "--predictors",
                str(sim / "truth_predictors.csv"),
                "--out",
                str(base / "forecast.csv"),
                "--quiet",
            ]
        )
        == 0
    )
    forecast = pd.read_csv(base / "forecast.csv")
    blind = forecast.copy()
    blind.loc[(blind["mode"] == 1) & (blind["phase"] == "forecast"), "ssi_frequency_hz"] = np.nan
    blind.to_csv(base / "forecast_blind.csv", index=False)
    (base / "a_folder").mkdir()
    (base / "a_file").write_text("x", encoding="utf-8")


def _npz(path: Path, **arrays) -> None:
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)


def _derived_accelerations(base: Path) -> None:
    n = 256
    good = dict(
        acceleration=response(n, 1),
        sampling_rate_hz=np.float64(RATE_HZ),
        start_time=np.str_("2026-03-01T00:00:00Z"),
        channels=np.array(CHANNELS),
    )
    (base / "numeric_start").mkdir()
    _npz(base / "numeric_start" / "a.npz", **{**good, "start_time": np.float64(1.7e9)})
    (base / "complex").mkdir()
    _npz(base / "complex" / "a.npz", **{**good, "acceleration": good["acceleration"] * (1 + 1j)})
    # a 1-KB archive whose array header claims 30 days of samples
    (base / "liar").mkdir()
    header = {"descr": "<f8", "fortran_order": False, "shape": (int(30 * 86400 * RATE_HZ), 4)}
    with zipfile.ZipFile(base / "liar" / "a.npz", "w") as archive:
        with archive.open("acceleration.npy", "w") as handle:
            np.lib.format.write_array_header_1_0(handle, header)
            handle.write(np.zeros(64).tobytes())
        for key in ("sampling_rate_hz", "start_time", "channels"):
            with archive.open(f"{key}.npy", "w") as handle:
                np.lib.format.write_array(handle, np.asarray(good[key]))
    # a file cut short mid-way among good ones, and the 1-KB liar among good ones: left
    # out, named in one warning (before: exit 1 for the whole voyage)
    paths = write_voyage(base / "one_cut", n_files=4)
    paths[1].write_bytes(paths[1].read_bytes()[: paths[1].stat().st_size // 2])
    write_voyage(base / "liar_among_good", n_files=4)
    (base / "liar_among_good" / "acc_004.npz").write_bytes((base / "liar" / "a.npz").read_bytes())
    # leftover of an interrupted write beside good files
    write_voyage(base / "leftover", n_files=4)
    (base / "leftover" / ".acc_004.npz.abc.tmp.npz").write_bytes(b"PK\x03\x04 truncated")
    # CSV accelerations: shuffled, duplicated, with a 10-s gap
    times = T0 + pd.to_timedelta(np.arange(n) / RATE_HZ, unit="s")
    frame = pd.DataFrame(good["acceleration"], columns=list(CHANNELS))
    frame.insert(0, "time", times.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))
    frame.sample(frac=1.0, random_state=0).to_csv(base / "shuffled.csv", index=False)
    dup = frame.copy()
    dup.loc[10, "time"] = dup.loc[9, "time"]
    dup.to_csv(base / "duplicated.csv", index=False)
    gap = frame.copy()
    later = T0 + pd.to_timedelta(np.arange(n) / RATE_HZ + 10.0 * (np.arange(n) >= 100), unit="s")
    gap["time"] = later.strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    gap.to_csv(base / "gap.csv", index=False)
    # stores: corrupt store.json, empty store.json, a damaged batch
    argv = ["identify", str(base / "voyage"), "--out", str(base / "damaged"), *IDENTIFY_ARGS]
    assert main(argv) == 0
    batch = next((base / "damaged" / "store" / "blocks").rglob("*.parquet"))
    batch.write_bytes(batch.read_bytes()[: len(batch.read_bytes()) // 2])  # torn by a bad disk
    for name, text in (("store_corrupt", "{not json"), ("store_empty", "")):
        (base / name).mkdir()
        (base / name / "store.json").write_text(text, encoding="utf-8")


SIM = "{root}/sim"
MODAL = ["--modal", "{root}/sim/tracked_modal.csv"]
PRED = ["--predictors", "{root}/sim/truth_predictors.csv"]
IDENT = ["identify", "{root}/voyage", "--out", "{tmp}/out", *IDENTIFY_ARGS]

CASES = {
    # ------------------------------------------------------------------ identify options
    "band above Nyquist": ([*IDENT, "--band", "2", "40"], 2, "--band"),
    "band from 0 Hz is a low-pass": ([*IDENT, "--band", "0", "12"], 0, "3 block(s) processed"),
    "rate 0": ([*IDENT, "--rate", "0"], 2, "--rate"),
    "rate nan": ([*IDENT, "--rate", "nan"], 2, "--rate"),
    "rate not a divisor": ([*IDENT, "--rate", "5"], 2, "whole number"),
    "unknown reference": ([*IDENT, "--reference-channels", "acc99"], 2, "acc99 not among"),
    "huge block rows": ([*IDENT, "--block-rows", "5000", "--max-order", "16"], 2, "samples"),
    "block minutes 0": ([*IDENT, "--block-minutes", "0"], 2, "--block-minutes"),
    "max gap negative": ([*IDENT, "--max-gap", "-1"], 2, "--max-gap"),
    "batch blocks 0": ([*IDENT, "--batch-blocks", "0"], 2, "--batch-blocks"),
    "scheduler bogus": ([*IDENT, "--scheduler", "bogus"], 2, "--scheduler"),
    "workers -2": ([*IDENT, "--workers", "-2"], 2, "--workers"),
    "workers 0": ([*IDENT, "--workers", "0"], 2, "--workers"),
    "figures -1": ([*IDENT, "--stabilisation-figures", "-1"], 2, "--stabilisation-figures"),
    "out is a file": (
        ["identify", "{root}/voyage", "--out", "{root}/a_file", *IDENTIFY_ARGS],
        1,
        "a_file: output folder is a file",
    ),
    "out under a file": (
        ["identify", "{root}/voyage", "--out", "{root}/a_file/x", *IDENTIFY_ARGS],
        1,
        "a_file",
    ),
    "store is a file": ([*IDENT, "--store", "{root}/a_file"], 1, "store is a file"),
    "store.json corrupt": ([*IDENT, "--store", "{root}/store_corrupt"], 1, "move it aside"),
    "store.json empty": ([*IDENT, "--store", "{root}/store_empty"], 1, "move it aside"),
    "stored batch damaged": (  # found by its checksum, its blocks computed again
        ["identify", "{root}/voyage", "--out", "{root}/damaged", *IDENTIFY_ARGS],
        0,
        "shorter than written",
    ),
    "hidden leftover ignored": (
        ["identify", "{root}/leftover", "--out", "{tmp}/out", *IDENTIFY_ARGS],
        0,
        "3 block(s) processed",
    ),
    "header claims 30 days": (  # the only file: nothing can be identified
        ["identify", "{root}/liar", "--out", "{tmp}/out", *IDENTIFY_ARGS],
        1,
        "a.npz: unreadable (array acceleration declares",
    ),
    "header claims 30 days beside good files": (
        ["identify", "{root}/liar_among_good", "--out", "{tmp}/out", *IDENTIFY_ARGS],
        0,
        "acc_004.npz: unreadable (array acceleration declares",
    ),
    "a file cut short among good ones": (
        ["identify", "{root}/one_cut", "--out", "{tmp}/out", *IDENTIFY_ARGS],
        0,
        "acc_001.npz: unreadable (not a valid .npz acceleration file",
    ),
    "numeric start_time": (
        ["validate", "accelerations", "{root}/numeric_start/a.npz"],
        1,
        "got the number",
    ),
    "complex samples": (["validate", "accelerations", "{root}/complex/a.npz"], 1, "complex values"),
    "csv shuffled": (["validate", "accelerations", "{root}/shuffled.csv"], 1, "times go backwards"),
    "csv duplicated": (
        ["validate", "accelerations", "{root}/duplicated.csv"],
        1,
        "duplicate sample times",
    ),
    "csv gap": (["validate", "accelerations", "{root}/gap.csv"], 1, "uneven sampling"),
    # ------------------------------------------------------------------ joins on block times
    "correlate predictors of another day": (
        ["correlate", *MODAL, "--predictors", "{root}/predictors_next_day.csv", "--out", "{tmp}/c"],
        1,
        "block numbers must mean the same times",
    ),
    "correlate predictors shifted a block": (
        ["correlate", *MODAL, "--predictors", "{root}/predictors_shifted.csv", "--out", "{tmp}/c"],
        1,
        "by -300 s",
    ),
    "fit predictors of another day": (
        ["fit", *MODAL, "--predictors", "{root}/predictors_next_day.csv", "--out", "{tmp}/f"],
        1,
        "block numbers must mean the same times",
    ),
    "forecast predictors shifted": (
        [
            "forecast",
            *MODAL,
            "--predictors",
            "{root}/predictors_shifted.csv",
            "--out",
            "{tmp}/f.csv",
        ],
        1,
        "predictors_shifted.csv: block 1 starts",
    ),
    "forecast poles of another voyage": (
        [
            "forecast",
            *MODAL,
            *PRED,
            "--option",
            "B",
            "--poles",
            "{root}/other/poles.parquet",
            "--out",
            "{tmp}/f.csv",
        ],
        1,
        "poles of another voyage",
    ),
    "forecast with its own voyage's poles": (
        [
            "forecast",
            *MODAL,
            *PRED,
            "--option",
            "B",
            "--poles",
            "{root}/sim/poles.parquet",
            "--out",
            "{tmp}/f.csv",
        ],
        0,
        "option(s) B",
    ),
    "correlate ship log not overlapping": (
        ["correlate", *MODAL, "--dship", "{root}/dship_late.tsv", "--out", "{tmp}/c"],
        1,
        "does not overlap",
    ),
    "evaluate truth of another day": (
        ["evaluate", "--forecast", "{root}/forecast.csv", "--truth", "{root}/truth_next_day.csv"],
        1,
        "truth_next_day.csv: block 0 starts",
    ),
    "block 1e18 with a ship log": (
        [
            "correlate",
            "--modal",
            "{root}/modal_block_1e18.csv",
            "--dship",
            "{root}/sim/dship.tsv",
            "--out",
            "{tmp}/c",
        ],
        1,
        "block 1000000000000000000 starts",
    ),
    # ------------------------------------------------------------------ tables
    "modal header only": (
        ["correlate", "--modal", "{root}/modal_header_only.csv", *PRED, "--out", "{tmp}/c"],
        1,
        "no rows",
    ),
    "block 1e18": (
        ["correlate", "--modal", "{root}/modal_block_1e18.csv", *PRED, "--out", "{tmp}/c"],
        1,
        "block",
    ),
    # any suffix is read as delimited text (other tools write .txt); what is not a table
    # is one line naming the file
    "modal not a table": (
        ["correlate", "--modal", "{root}/modal.bin", *PRED, "--out", "{tmp}/c"],
        1,
        "cannot read file",
    ),
    "ragged ship log": (
        ["correlate", *MODAL, "--dship", "{root}/dship_ragged.tsv", "--out", "{tmp}/c"],
        1,
        "dship_ragged.tsv",
    ),
    "case named all": (
        ["correlate", *MODAL, *PRED, "--cases", "{root}/cases_all.csv", "--out", "{tmp}/c"],
        1,
        "the case name 'all' is reserved",
    ),
    "mathtext predictor name": (
        [
            "correlate",
            *MODAL,
            "--predictors",
            "{root}/predictors_mathtext.csv",
            "--all-predictors",
            "--out",
            "{tmp}/c",
        ],
        0,
        "html",
    ),
    "correlate with an all-NaN predictor is quiet": (
        [
            "correlate",
            *MODAL,
            "--predictors",
            "{root}/predictors_dead_column.csv",
            "--out",
            "{tmp}/c",
        ],
        0,
        "html",
    ),
    "normal correlate is quiet": (
        ["correlate", *MODAL, *PRED, "--cases", "{root}/sim/cases.csv", "--out", "{tmp}/c"],
        0,
        "html",
    ),
    # ------------------------------------------------------------------ stage options
    "correlate out is a file": (
        ["correlate", *MODAL, *PRED, "--out", "{root}/a_file"],
        1,
        "a_file",
    ),
    "track mac min 2": (
        ["track", "{root}/sim/tracked_modal.csv", "--out", "{tmp}/t.csv", "--mac-min", "2"],
        2,
        "--mac-min",
    ),
    "track out suffix": (
        ["track", "{root}/sim/tracked_modal.csv", "--out", "{tmp}/t.txt"],
        2,
        ".csv or .parquet",
    ),
    "forecast horizon 0": (
        ["forecast", *MODAL, *PRED, "--out", "{tmp}/f.csv", "--horizon", "0"],
        2,
        "--horizon",
    ),
    "forecast min presence 2": (
        ["forecast", *MODAL, *PRED, "--out", "{tmp}/f.csv", "--min-presence", "2"],
        2,
        "--min-presence",
    ),
    "correlate min presence 2": (
        ["correlate", *MODAL, *PRED, "--out", "{tmp}/c", "--min-presence", "2"],
        2,
        "--min-presence",
    ),
    "forecast shape mac 5": (
        ["forecast", *MODAL, *PRED, "--out", "{tmp}/f.csv", "--mac-min", "5"],
        2,
        "--mac-min",
    ),
    "forecast workers -4": (
        ["forecast", *MODAL, *PRED, "--out", "{tmp}/f.csv", "--workers", "-4"],
        2,
        "--workers",
    ),
    "forecast out is a folder": (
        ["forecast", *MODAL, *PRED, "--out", "{root}/a_folder"],
        2,
        "a_folder",
    ),
    "fit bad upper": (
        ["fit", *MODAL, *PRED, "--out", "{tmp}/f", "--upper", "y ~ speed_kn + nonsense"],
        2,
        "nonsense",
    ),
    "simulate hours inf": (["simulate", "--out", "{tmp}/s", "--hours", "inf"], 2, "--hours"),
    "simulate hours 1e7": (["simulate", "--out", "{tmp}/s", "--hours", "1e7"], 2, "--hours"),
    "evaluate no SSI in phase": (
        [
            "evaluate",
            "--forecast",
            "{root}/forecast_blind.csv",
            "--truth",
            "{root}/sim/truth_modal.csv",
        ],
        0,
        "option A",
    ),
    "evaluate out is a folder": (
        [
            "evaluate",
            "--forecast",
            "{root}/forecast.csv",
            "--truth",
            "{root}/sim/truth_modal.csv",
            "--out",
            "{root}/a_folder",
        ],
        2,
        "a_folder",
    ),
}


@pytest.mark.parametrize(("command", "code", "fragment"), list(CASES.values()), ids=list(CASES))
def test_case(root, tmp_path, capsys, command, code, fragment):
    argv = [part.format(root=root, tmp=tmp_path) for part in command]
    status = main(argv)
    out, err = capsys.readouterr()
    assert status == code, f"exit {status}, stderr: {err[-2000:]}"
    assert fragment in out + err
    assert "Traceback" not in err and "np.float64(" not in out + err
    assert "Mean of empty slice" not in err and "RuntimeWarning" not in err
    if code:
        lines = [line for line in err.splitlines() if not line.startswith("warning:")]
        assert len(lines) == 1, err
    if code == 2:  # usage errors do not blame an input file
        assert str(root) not in err or fragment.startswith(("a_", "{"))


def test_evaluate_writes_real_parquet(root, tmp_path):
    from data_contracts import FORECAST, MODAL, read_table
    from workbench.stages import evaluate

    out = tmp_path / "evaluation.parquet"
    argv = ["evaluate", "--forecast", f"{root}/forecast.csv", "--truth"]
    assert main([*argv, f"{root}/sim/truth_modal.csv", "--out", str(out)]) == 0
    assert out.read_bytes()[:4] == b"PAR1"
    expected = evaluate(
        read_table(root / "forecast.csv", FORECAST),
        read_table(root / "sim" / "truth_modal.csv", MODAL),
    ).table
    pd.testing.assert_frame_equal(pd.read_parquet(out), expected.reset_index(drop=True))


def test_evaluate_without_ssi_in_the_phase_gives_nan_improvement(root, tmp_path):
    out = tmp_path / "evaluation.csv"
    argv = ["evaluate", "--forecast", f"{root}/forecast_blind.csv", "--truth"]
    assert main([*argv, f"{root}/sim/truth_modal.csv", "--out", str(out)]) == 0
    table = pd.read_csv(out)
    blind = table[table["mode"] == table["mode"].min()]
    assert (blind["n_ssi"] == 0).all() and blind["improvement_vs_ssi_pct"].isna().all()
    assert table["improvement_vs_ssi_pct"].notna().any()


def test_a_file_lacking_a_channel_is_identified_without_it(tmp_path, capsys, caplog):
    """A recorder that drops a channel for one file: identify goes on (before: exit 1 for
    the whole voyage), warns naming the file, and drops the channel only in the blocks
    holding that file; the summary's notes are lines of their own (before: a literal
    backslash-n joined them)."""
    paths = write_voyage(tmp_path / "voyage", n_files=4)
    record = np.load(paths[1], allow_pickle=False)
    _npz(
        paths[1],
        acceleration=record["acceleration"][:, [0, 1, 3]],
        sampling_rate_hz=record["sampling_rate_hz"],
        start_time=record["start_time"],
        channels=np.array([c for c in CHANNELS if c != "acc03"]),
    )
    argv = ["identify", str(tmp_path / "voyage"), "--out", str(tmp_path / "out"), *IDENTIFY_ARGS]
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert "acc_001.npz: channel(s) acc03 missing" in caplog.text + err
    assert "\\n" not in out
    assert "  note (2): channel acc03 dropped (nan fraction)" in out.splitlines()
    faults = pd.read_csv(tmp_path / "out" / "faults.csv")
    assert faults.loc[faults["channel"] == "acc03", "block"].tolist() == [0, 1]
