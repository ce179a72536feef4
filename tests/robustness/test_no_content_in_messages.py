"""A text file given by mistake (a key, a password file) is refused without its content.

Before: a file whose first line is one undelimited field, given as a modal table
(``correlate --modal``, ``evaluate --truth``) or as accelerations (``validate``,
``identify``), was refused with "columns in the file: <that line>" - the line itself, a
password or a key, on stderr. The ship-log reader already said "header has a single
column" without quoting it; now every reader does: the file is named, its first line is
not shown. Column names of a delimited header are still listed.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from workbench.cli import main

SECRET = "sk-live-7f3a9c0e1b2d"


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    folder = tmp_path_factory.mktemp("no_content") / "sim"
    simulate_voyage(folder, seed=0, hours=4, accelerations=False)
    argv = ["forecast", "--modal", folder / "tracked_modal.csv", "--predictors"]
    argv += [folder / "truth_predictors.csv", "--out", folder / "forecast.csv", "--quiet"]
    assert main([str(a) for a in argv]) == 0
    return folder


@pytest.mark.parametrize("name", ["credentials.txt", "credentials.csv", "credentials"])
@pytest.mark.parametrize("command", ["correlate", "evaluate", "validate"])
def test_a_one_field_first_line_is_not_shown(sim, tmp_path, capsys, name, command):
    path = tmp_path / name
    path.write_text(f"API_KEY={SECRET}\npassword: hunter2\n", encoding="utf-8")
    argv = {
        "correlate": ["correlate", "--modal", path, "--predictors"]
        + [sim / "truth_predictors.csv", "--out", tmp_path / "c"],
        "evaluate": ["evaluate", "--forecast", sim / "forecast.csv", "--truth", path],
        "validate": ["validate", "accelerations", path],
    }[command]
    status = main([str(a) for a in argv])
    captured = capsys.readouterr()
    assert status == 1
    assert SECRET not in captured.out + captured.err
    assert "hunter2" not in captured.out + captured.err
    assert str(path) in captured.err
    assert len(captured.err.strip().splitlines()) == 1


def test_a_delimited_header_is_still_listed(sim, tmp_path, capsys):
    path = tmp_path / "other.csv"
    path.write_text("alpha,beta\n1,2\n", encoding="utf-8")
    argv = ["correlate", "--modal", path, "--predictors", sim / "truth_predictors.csv"]
    assert main([str(a) for a in [*argv, "--out", tmp_path / "c"]]) == 1
    assert "columns in the file: alpha, beta" in capsys.readouterr().err
