"""A ship's set-up in a TOML file: checking, --config on the commands, `workbench run`."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import build_parser, main
from workbench.config import (
    ConfigError,
    apply_config,
    chain,
    command_defaults,
    load_config,
    write_demo_config,
)


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_unknown_sections_keys_and_types_are_refused(tmp_path):
    path = write(
        tmp_path / "ship.toml",
        '[dship]\nfile = "log.dat"\ncolumn = {}\n[forecst]\ntrain = 5\n[forecast]\ntrain_blocks = "20"\n',
    )
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    lines = str(caught.value).splitlines()
    assert lines == [
        f"{path}: [dship] unknown key 'column' (did you mean 'columns'? known: file, columns)",
        f"{path}: unknown section [forecst] (did you mean 'forecast'? known: output, "
        "times, accelerations, dship, predictors, modal, blocks, identify, track, correlate, fit, "
        "forecast, evaluate)",
        f"{path}: [forecast] train_blocks = '20' has the wrong type",
    ]
    assert main(["correlate", "--config", str(path)]) == 2
    assert main(["run", str(path)]) == 2


def test_paths_relative_to_the_file_and_flags_win(tmp_path):
    (tmp_path / "cfg").mkdir()
    path = write(
        tmp_path / "cfg" / "ship.toml",
        '[modal]\nfile = "modes.csv"\ndamping_unit = "percent"\n'
        '[dship]\nfile = "../logs/dship.dat"\ncolumns = { speed_kn = "SYS.STR.SOG" }\n'
        "[blocks]\nlength_minutes = 30\nstep_minutes = 10\n"
        "[correlate]\nalpha = 0.01\n",
    )
    config = load_config(path)
    defaults = command_defaults("correlate", config)
    assert defaults["modal"] == tmp_path / "cfg" / "modes.csv"
    assert defaults["dship"] == tmp_path / "cfg" / ".." / "logs" / "dship.dat"
    assert defaults["dship_columns"] == ["speed_kn=SYS.STR.SOG"]
    assert defaults["grid"] == "30,10" and defaults["damping_unit"] == "percent"
    parser = build_parser()
    apply_config(parser, config)
    args = parser.parse_args(["correlate", "--alpha", "0.2"])  # --modal/--out not needed
    assert args.alpha == 0.2 and args.modal == tmp_path / "cfg" / "modes.csv"
    assert args.out == tmp_path / "cfg" / "out" / "correlation"
    args = parser.parse_args(["correlate"])
    assert args.alpha == 0.01


def test_block_length_auto_reaches_identify_and_the_monitor(tmp_path):
    """``[blocks] length_minutes = "auto"``: identify and the monitor parse
    ``--block-minutes auto`` from it; the commands that read a modal file get no grid of
    one length from it (blocks of varying length carry their own grid record)."""
    path = write(
        tmp_path / "ship.toml",
        '[accelerations]\ninputs = ["acc"]\n[modal]\nfile = "modes.csv"\n'
        '[blocks]\nlength_minutes = "auto"\nstep_minutes = 5\n',
    )
    config = load_config(path)
    assert command_defaults("identify", config)["block_minutes"] == "auto"
    assert command_defaults("monitor", config)["block_minutes"] == "auto"
    assert "grid" not in command_defaults("forecast", config)
    parser = build_parser()
    apply_config(parser, config)
    for command in ("identify", "monitor"):
        args = parser.parse_args([command])
        assert args.block_minutes == "auto", (command, args.block_minutes)


def test_demo_config_reads_back_and_runs_the_whole_chain(tmp_path):
    path = write_demo_config(tmp_path)
    config = load_config(path)
    assert [step[0] for step in chain(config)] == [
        "identify",
        "track",
        "correlate",
        "fit",
        "forecast",
        "evaluate",
        "report",
    ]
    identify = command_defaults("identify", config)
    assert identify["inputs"] == [tmp_path / "voyage" / "accelerations"]
    assert identify["band"] == (2.0, 12.0)
    assert command_defaults("forecast", config)["poles"] == (
        tmp_path / "ship_run" / "identify" / "poles.parquet"
    )


def test_run_a_foreign_modal_table_and_ship_log(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path), "--hours", "3", "--no-accelerations"]) == 0
    tracked = pd.read_csv(tmp_path / "tracked_modal.csv")
    # the table as another tool writes it: long, centre times, damping in %
    foreign = pd.DataFrame(
        {
            "Time": (pd.to_datetime(tracked["block_start"]) + pd.Timedelta(minutes=10)).dt.strftime(
                "%Y-%m-%dT%H:%M:%SZ"
            ),
            "Mode": tracked["mode"],
            "Frequency [Hz]": tracked["frequency_hz"],
            "Damping [%]": 100 * tracked["damping_ratio"],
        }
    )
    foreign.to_csv(tmp_path / "modes.csv", sep=";", decimal=",", index=False)
    config = write(
        tmp_path / "ship.toml",
        '[modal]\nfile = "modes.csv"\ntime_reference = "centre"\n'
        '[dship]\nfile = "dship.tsv"\n[forecast]\ntrain_blocks = 10\n'
        '[evaluate]\ntruth = "truth_modal.csv"\n',
    )
    capsys.readouterr()
    code = main(["run", str(config)])
    out, err = capsys.readouterr()
    assert code == 0, err
    for step in ("correlate", "fit", "forecast", "evaluate"):
        assert f"== workbench {step} --config" in out
    assert "Kalman" in out and (tmp_path / "out" / "evaluation.csv").is_file()
    # the run ends with its report, drawn from the foreign table the run started from
    assert "== workbench report --config" in out
    page = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "Modes found" in page and "Forecast" in page
    forecast = pd.read_csv(tmp_path / "out" / "forecast.csv")
    assert set(forecast["block"]) <= set(tracked["block"])
