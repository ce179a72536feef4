"""Progress bars where the user looks (issue 30): a terminal that reports no width, and a
Jupyter kernel without ipywidgets."""

from __future__ import annotations

import os
import select
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from workbench import progress

ROOT = Path(__file__).resolve().parents[1]


def _read_all(fd: int, timeout_s: float = 60.0) -> bytes:
    """Everything written to the pty's master until the writer closes it (bounded)."""
    out = b""
    for _ in range(10_000):  # bounded; each wait at most timeout_s
        ready, _, _ = select.select([fd], [], [], timeout_s)
        if not ready:
            break
        try:
            chunk = os.read(fd, 4096)
        except OSError:  # the slave side closed
            break
        if not chunk:
            break
        out += chunk
    return out


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_a_terminal_without_a_width_still_shows_the_bar():
    """Before: tqdm sized its bar to the terminal's 0 columns and drew nothing (no bar seen
    for identify, track or the demo in such a terminal). A fresh pty reports 0 x 0."""
    master, slave = os.openpty()
    assert os.get_terminal_size(slave).columns == 0
    code = (
        "from workbench.progress import progress_bar\n"
        "for _ in progress_bar(range(7), description='identify'):\n"
        "    pass\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
    env["PYTHONPATH"] = str(ROOT)
    child = subprocess.Popen(
        [sys.executable, "-c", code], stderr=slave, stdout=subprocess.DEVNULL, env=env
    )
    os.close(slave)
    text = _read_all(master).decode("utf-8", "replace")
    child.wait(timeout=60)
    os.close(master)
    assert child.returncode == 0
    last = text.replace("\r\n", "\n").split("\r")[-1].strip()
    assert last.startswith("identify: 100%") and "7/7" in last
    assert len(last) <= progress.FALLBACK_COLUMNS


def test_in_a_notebook_without_ipywidgets_a_text_bar_and_no_warning(monkeypatch, capsys):
    """Before: tqdm.auto warned 'IProgress not found. Please update jupyter and ipywidgets'
    and showed no bar."""
    monkeypatch.setattr(progress, "in_notebook", lambda: True)
    real_find_spec = progress.importlib.util.find_spec
    monkeypatch.setattr(
        progress.importlib.util,
        "find_spec",
        lambda name, *a: None if name == "ipywidgets" else real_find_spec(name, *a),
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        bar = progress.progress_bar(range(5), description="track")
        assert sum(1 for _ in bar) == 5
    assert not caught
    assert type(bar).__module__ == "tqdm.std" and bar.ncols == progress.FALLBACK_COLUMNS
    assert "track: 100%" in capsys.readouterr().err


def test_a_disabled_bar_writes_nothing(capsys):
    bar = progress.progress_bar(total=3, enabled=False)
    bar.update(3)
    bar.close()
    assert capsys.readouterr().err == ""
