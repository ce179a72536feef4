"""A monitor restarted over its state folder with another ship log, or the same log with
other settings, is refused before the folder is touched; the log grown by appended lines
(the follow mode) is taken up (:mod:`workbench.monitor.log_record`).

Main took any of them silently: the health chart went on from the model fitted on the
first log (a 7-h voyage restarted after 5 h with another log: 36 of its 45 health rows
differ from a fresh run's with that log; the forecast's committed windows beyond its kept
history likewise).
"""

from __future__ import annotations

import hashlib
import json
import shutil

import pytest

from workbench.errors import OptionError, WorkbenchError
from workbench.monitor.log_record import LOG_RECORD_FILE, ShipLogRecord

from .conftest import (
    FORECAST,
    IDENTIFY,
    MONITOR_FAST,
    ShipLog,
    assert_same_tables,
    cli,
    file_end,
    land,
)


def _snapshot(state) -> dict[str, str]:
    """Every file of the state folder and its SHA-256."""
    return {
        str(p.relative_to(state)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(state.rglob("*"))
        if p.is_file()
    }


def _once(watch, state, *log_options) -> int:
    return cli(
        "monitor", "--watch", watch, "--state", state, *log_options,
        *IDENTIFY, *FORECAST, *MONITOR_FAST, "--once", "--quiet",
    )  # fmt: skip


def test_a_restart_with_another_ship_log_is_refused_and_the_state_kept(
    voyage, batch, tmp_path, capsys
):
    watch, state = tmp_path / "watch", tmp_path / "state"
    files = sorted((voyage / "accelerations").glob("*.npz"))
    log_path = tmp_path / "dship.tsv"
    log = ShipLog(voyage / "dship.tsv", log_path)
    for path in files[:8]:
        land(path, watch)
    log.until(file_end(files[7]))
    assert _once(watch, state, "--dship", log_path) == 0
    capsys.readouterr()
    before = _snapshot(state)
    recorded = json.loads((state / LOG_RECORD_FILE).read_text(encoding="utf-8"))
    assert recorded["bytes"] == log_path.stat().st_size  # every whole line read
    assert recorded["sha256"] == hashlib.sha256(log_path.read_bytes()).hexdigest()

    # another log: the same voyage's, every speed 1 kn more (main: exit 0, its predictors
    # mixed with the first's)
    other = tmp_path / "other.tsv"
    rows = log_path.read_text(encoding="utf-8").splitlines(keepends=True)
    start = next(i for i, r in enumerate(rows) if r.startswith("*/")) + 2
    other.write_text(
        "".join(rows[:start])
        + "".join(
            "\t".join(
                [*r.split("\t")[:3], f"{float(r.split(chr(9))[3]) + 1:.1f}", *r.split("\t")[4:]]
            )
            for r in rows[start:]
        ),
        encoding="utf-8",
    )
    kept = "(or use another --state folder)"
    usage = {
        "another --dship": (
            ["--dship", other],
            f"workbench: error: --dship {other}: not the ship log the state folder {state} "
            f"was made with ({log_path}; the first {recorded['bytes']} bytes differ); give "
            f"that log {kept}",
        ),
        "other --dship-columns": (
            ["--dship", log_path, "--dship-columns", "speed_kn=Speed"],
            f"workbench: error: --dship-columns speed_kn=Speed: the state folder {state} was "
            f"made with --dship-columns (not given); give the same {kept}",
        ),
        "another --dship-utc-offset": (
            ["--dship", log_path, "--dship-utc-offset", "+01:00"],
            f"workbench: error: --dship-utc-offset +01:00: the state folder {state} was made "
            f"with --dship-utc-offset (not given); give the same {kept}",
        ),
        "no --dship": (
            [],
            f"workbench: error: --dship: the state folder {state} was made with the ship log "
            f"{log_path} ({recorded['bytes']} bytes read); give it again {kept}",
        ),
    }
    for what, (options, line) in usage.items():
        assert _once(watch, state, *options) == 2, what
        err = capsys.readouterr().err
        assert err.splitlines() == [line], what
    # the log itself rewritten in an earlier row: a changed input, bad data
    shutil.copy(log_path, tmp_path / "kept.tsv")
    shutil.copy(other, log_path)
    assert _once(watch, state, "--dship", log_path) == 1
    assert capsys.readouterr().err.splitlines() == [
        f"error: {log_path}: changed since the state folder {state} read it (its first "
        f"{recorded['bytes']} bytes differ: rewritten or replaced); its forecast and health "
        f"chart came from the log as it was: give it so {kept}"
    ]
    log_path.write_text("".join(rows[: start + 9]), encoding="utf-8")  # cut short
    assert _once(watch, state, "--dship", log_path) == 1
    assert "fewer than the" in capsys.readouterr().err
    assert _snapshot(state) == before  # nothing touched by the refused restarts

    # the log as it was, grown by the rows since (the follow mode): taken up, and the
    # tables end as the batch run's over the whole voyage
    shutil.copy(tmp_path / "kept.tsv", log_path)
    log.until(None)
    for path in files[8:]:
        land(path, watch)
    assert _once(watch, state, "--dship", log_path) == 0
    assert_same_tables(state, batch)
    recorded = json.loads((state / LOG_RECORD_FILE).read_text(encoding="utf-8"))
    assert recorded["bytes"] == log_path.stat().st_size


def _record(tmp_path, dship, columns=None, offset=None):
    return ShipLogRecord(tmp_path / "state", dship, columns or {}, offset)


def test_the_record_follows_the_log_and_takes_it_moved(tmp_path):
    (tmp_path / "state").mkdir()
    log = tmp_path / "log.tsv"
    log.write_bytes(b"header\nrow 1\nrow 2\n")
    first = _record(tmp_path, log)
    assert first.check(has_results=False) == []  # a new folder: nothing to check
    first.update((13, hashlib.sha256(b"header\nrow 1\n").hexdigest()))  # 2 lines read
    # the same bytes under another name: the same log, moved (said in a note)
    moved = tmp_path / "moved.tsv"
    shutil.copy(log, moved)
    notes = _record(tmp_path, moved).check(has_results=True)
    assert notes == [
        f"ship log now {moved}: its first 13 bytes are those of {log} that the state "
        "folder's results came from"
    ]
    # the UTC offset compared as the reader takes it: +00:00 is UTC, as none given
    assert _record(tmp_path, log, offset="UTC+00:00").check(has_results=True) == []
    with pytest.raises(OptionError, match=r"^--dship-utc-offset \+02:00: the state folder"):
        _record(tmp_path, log, offset="+02:00").check(has_results=True)
    # a row beyond those read rewritten: not what the results came from, taken
    log.write_bytes(b"header\nrow 1\nrow X\n")
    assert _record(tmp_path, log).check(has_results=True) == []
    log.write_bytes(b"header\nrow Y\nrow 2\n")
    with pytest.raises(WorkbenchError, match="its first 13 bytes differ"):
        _record(tmp_path, log).check(has_results=True)
    log.unlink()
    with pytest.raises(WorkbenchError, match=f"{log}: changed since .* read it \\(gone\\)"):
        _record(tmp_path, log).check(has_results=True)
    with pytest.raises(OptionError, match=r"\(log.tsv; no such file\)|no such file"):
        _record(tmp_path, tmp_path / "nowhere.tsv").check(has_results=True)


def test_a_folder_without_the_record_or_with_nothing_read_takes_any_log(tmp_path):
    (tmp_path / "state").mkdir()
    log = tmp_path / "log.tsv"
    log.write_bytes(b"header\nrow 1\n")
    # results but no record (a folder of an earlier version): recorded now, said so
    (note,) = _record(tmp_path, log).check(has_results=True)
    assert note.endswith(
        "ship_log.json: absent: the ship log is recorded as this run gives it, unchecked "
        "against the one the state folder's results came from"
    )
    # a log given but never read (absent then): nothing came from it, any log taken
    _record(tmp_path, tmp_path / "not_yet.tsv").update()
    assert _record(tmp_path, log, {"speed_kn": "SOG"}, "+02:00").check(has_results=True) == []
    # no log at all before: a log given now is taken
    _record(tmp_path, None).update()
    assert _record(tmp_path, log).check(has_results=True) == []
    # an unreadable record: said, recorded again
    (tmp_path / "state" / LOG_RECORD_FILE).write_text("{", encoding="utf-8")
    (note,) = _record(tmp_path, log).check(has_results=True)
    assert "ship_log.json: unreadable (" in note
