"""Input fingerprints (workbench.identification.planning.input_fingerprints): hashed on
several threads, in the order of the plan's files, each the SHA-256 of every byte."""

from __future__ import annotations

import hashlib
from types import SimpleNamespace

import pandas as pd
import pytest

from workbench.errors import WorkbenchError
from workbench.identification.planning import input_fingerprints


def _info(path, k):
    start = pd.Timestamp("2024-01-01", tz="UTC") + pd.Timedelta(minutes=5 * k)
    return SimpleNamespace(path=path, start_time=start, end_time=start + pd.Timedelta(minutes=5))


def test_fingerprints_in_plan_order_with_the_content_hash(tmp_path):
    infos = []
    for k in range(5):
        path = tmp_path / f"f{k}.npz"
        path.write_bytes(bytes([k]) * (300_000 + 7 * k))
        infos.append(_info(path, k))
    infos.reverse()  # the order given is kept, not the folder's
    prints = input_fingerprints(infos)
    assert [p["path"] for p in prints] == [str(i.path.resolve()) for i in infos]
    for info, p in zip(infos, prints, strict=True):
        assert p["sha256"] == hashlib.sha256(info.path.read_bytes()).hexdigest()
        assert p["size"] == info.path.stat().st_size
        assert p["start"] == info.start_time.isoformat()


def test_unreadable_file_names_the_file(tmp_path):
    good = tmp_path / "a.npz"
    good.write_bytes(b"x")
    with pytest.raises(WorkbenchError) as raised:
        input_fingerprints([_info(good, 0), _info(tmp_path / "missing.npz", 1)])
    assert "missing.npz: cannot read" in str(raised.value)
