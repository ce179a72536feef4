"""Readers cannot be turned against the machine (issue 34, readers).

* Data outside the file: an HDF5 acceleration file (``.h5``) whose ``start_time``,
  ``units``, ``channels``, ``sampling_rate_hz`` or acceleration matrix lives in another
  file (external storage, an external link, a soft link through an external link, a
  virtual dataset), or a MATLAB v7.3 cell pointing at an anonymous external dataset, is
  refused before anything is read: the other file's token never appears in stdout, stderr
  or any file written (validate and identify).
* Declared sizes: an HDF5 / MATLAB dataset declaring more than the file stores, or more
  than the memory budget (``WORKBENCH_MAX_ARRAY_BYTES``), is refused before it is read (a
  guard on ``h5py.Dataset.__getitem__`` fails the test if a large read is attempted); a
  CSV header of more than 1024 columns is refused before parsing; option ranges
  (``--max-order``, ``--lscf-max-order``, ``max_order`` in a config, ``--step-minutes``) are
  refused (exit 2) before anything is built from them.
* UFF records: cut files, 2-sample records, a declared length other than the data's and a
  zero increment are refused.
* Messages: control characters in file names are escaped; a garbage ``.npz`` is one plain
  line that does not mention pickles.
"""

from __future__ import annotations

import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from data_contracts import ContractError, read_accelerations
from data_contracts.limits import (
    DEFAULT_MAX_ARRAY_BYTES,
    MAX_ARRAY_BYTES_VARIABLE,
    MAX_CHANNELS,
    max_array_bytes,
)
from workbench.cli import main

from .voyage import CHANNELS, IDENTIFY_ARGS, RATE_HZ, response

SECRET = "SECRET-TOKEN-34-readers"
START = "2026-03-01T00:00:00Z"
#: 4 minutes at 32 Hz: two 2-minute blocks for identify (IDENTIFY_ARGS).
N_SAMPLES = int(240 * RATE_HZ)


def _run(argv) -> int:
    return main([str(a) for a in argv])


def _assert_nowhere(secret: str, capsys, *folders: Path) -> str:
    """The secret is in neither stdout, stderr nor any file under *folders* (but the
    ``secret`` folder holding it); returns stderr."""
    out, err = capsys.readouterr()
    assert secret not in out and secret not in err
    token = secret.encode()
    for folder in folders:
        for path in Path(folder).rglob("*"):
            if path.is_file() and path.parent.name != "secret":
                data = path.read_bytes()
                assert token not in data and secret.encode("utf-16-le") not in data, path
    return err


# ---------------------------------------------------------------------- data in other files
@pytest.fixture
def secret(tmp_path) -> Path:
    path = tmp_path / "secret" / "secret.txt"
    path.parent.mkdir()
    path.write_bytes(SECRET.encode())
    return path


def _h5(path: Path, *, skip: str | None = None, data=None) -> h5py.File:
    """An acceleration .h5 file, open for more datasets (*skip* one of the usual ones)."""
    handle = h5py.File(path, "w")
    values = {
        "acceleration": response(N_SAMPLES, 1) if data is None else data,
        "sampling_rate_hz": np.float64(RATE_HZ),
        "start_time": START,
        "channels": np.array([c.encode() for c in CHANNELS]),
    }
    for name, value in values.items():
        if name != skip:
            handle[name] = value
    return handle


def _other_file(tmp_path: Path, secret: Path, shape, dtype) -> Path:
    """An HDF5 file whose dataset /x holds the secret's bytes."""
    other = tmp_path / "secret" / "other.h5"
    raw = secret.read_bytes()
    count = int(np.prod(shape)) * np.dtype(dtype).itemsize
    with h5py.File(other, "w") as handle:
        handle["x"] = np.frombuffer((raw * (count // len(raw) + 1))[:count], dtype).reshape(shape)
    return other


#: What each target holds when it points outside: shape and dtype of the stored bytes.
TARGETS = {
    "start_time": ((1,), f"S{len(SECRET)}"),
    "units": ((1,), f"S{len(SECRET)}"),
    "channels": ((len(CHANNELS),), "S6"),
    "sampling_rate_hz": ((1,), "f8"),
}


def _point_outside(handle, tmp_path, secret, name, kind, shape, dtype) -> None:
    if kind == "external storage":
        size = int(np.prod(shape)) * np.dtype(dtype).itemsize
        handle.create_dataset(name, shape=shape, dtype=dtype, external=[(str(secret), 0, size)])
    elif kind == "external link":
        handle[name] = h5py.ExternalLink(str(_other_file(tmp_path, secret, shape, dtype)), "/x")
    elif kind == "soft link through an external link":
        other = _other_file(tmp_path, secret, shape, dtype)
        handle["elsewhere"] = h5py.ExternalLink(str(other), "/")
        handle[name] = h5py.SoftLink("/elsewhere/x")
    else:  # virtual dataset
        other = _other_file(tmp_path, secret, shape, dtype)
        layout = h5py.VirtualLayout(shape=shape, dtype=dtype)
        layout[:] = h5py.VirtualSource(str(other), "x", shape=shape)
        handle.create_virtual_dataset(name, layout)


KINDS = {
    "external storage": "HDF5 external storage",
    "external link": "HDF5 external link",
    "soft link through an external link": "HDF5 external link",
    "virtual dataset": "HDF5 virtual dataset",
}


def test_plain_h5_file_is_valid(tmp_path, capsys):
    with _h5(tmp_path / "ok.h5"):
        pass
    assert _run(["validate", "accelerations", tmp_path / "ok.h5"]) == 0
    assert f"{N_SAMPLES} samples x 4 channels at 32 Hz" in capsys.readouterr().out


@pytest.mark.parametrize("kind", list(KINDS))
@pytest.mark.parametrize("target", list(TARGETS))
def test_h5_data_in_another_file_is_refused_unread(tmp_path, secret, capsys, target, kind):
    path = tmp_path / "crafted.h5"
    with _h5(path, skip=None if target == "units" else target) as handle:
        _point_outside(handle, tmp_path, secret, target, kind, *TARGETS[target])
    assert _run(["validate", "accelerations", path]) == 1
    err = _assert_nowhere(SECRET, capsys, tmp_path)
    assert KINDS[kind] in err and "crafted.h5" in err
    assert len(err.strip().splitlines()) == 1, err


def test_h5_channels_outside_never_reach_the_tables(tmp_path, secret, capsys):
    """The reported case: external ``channels`` validated, then identify wrote the token
    into channels.csv, poles/selected.parquet and store.json."""
    path = tmp_path / "voyage" / "rec.h5"
    path.parent.mkdir()
    with _h5(path, skip="channels") as handle:
        shape, dtype = TARGETS["channels"]
        _point_outside(handle, tmp_path, secret, "channels", "external storage", shape, dtype)
    out = tmp_path / "out"
    assert _run(["identify", path.parent, "--out", out, *IDENTIFY_ARGS]) == 1
    err = _assert_nowhere(SECRET, capsys, tmp_path / "voyage", out)
    assert "HDF5 external storage" in err and "channels" in err


def test_h5_virtual_acceleration_matrix_is_refused(tmp_path, secret, capsys):
    other = tmp_path / "secret" / "other.h5"
    with h5py.File(other, "w") as handle:
        handle["x"] = response(N_SAMPLES, 2)
    path = tmp_path / "virtual.h5"
    with _h5(path, skip="acceleration") as handle:
        layout = h5py.VirtualLayout(shape=(N_SAMPLES, 4), dtype="f8")
        layout[:] = h5py.VirtualSource(str(other), "x", shape=(N_SAMPLES, 4))
        handle.create_virtual_dataset("acceleration", layout)
    with pytest.raises(ContractError) as caught:
        read_accelerations(path)
    assert "HDF5 virtual dataset" in str(caught.value) and "/acceleration" in str(caught.value)


def test_mat73_cell_pointing_at_an_external_dataset_is_refused(tmp_path, secret):
    """A MATLAB cell array of object references into ``#refs#``, one of them stored in
    another file: refused before the cell is read."""
    path = tmp_path / "crafted.mat"
    n = len(SECRET) // 2
    with h5py.File(path, "w") as mat:
        mat["acceleration"] = response(N_SAMPLES, 1).T
        mat["sampling_rate_hz"] = np.array([[RATE_HZ]])
        mat["start_time"] = np.array([ord(c) for c in START], dtype="u2")
        cells = [
            mat.create_dataset(f"#refs#/c{j}", data=np.array([ord(c) for c in name], "u2"))
            for j, name in enumerate(CHANNELS[:-1])
        ]
        outside = [(str(secret), 0, 2 * n)]
        cells.append(mat.create_dataset("#refs#/c3", shape=(n,), dtype="u2", external=outside))
        mat.create_dataset("channels", data=np.array([c.ref for c in cells]), dtype=h5py.ref_dtype)
    with pytest.raises(ContractError) as caught:
        read_accelerations(path)
    message = str(caught.value)
    assert "HDF5 external storage" in message and "#refs#/c3" in message
    assert SECRET[:n] not in message


def test_hard_link_cycle_ends(tmp_path):
    path = tmp_path / "cycle.h5"
    with _h5(path) as handle:
        group = handle.create_group("g")
        group["loop"] = group  # /g/loop is /g
    record = read_accelerations(path)
    assert record.channels == CHANNELS


# ---------------------------------------------------------------------- declared sizes
@pytest.fixture
def no_large_reads(monkeypatch):
    """Fail (inside the reader, so the message shows it) if a large dataset is read."""
    original = h5py.Dataset.__getitem__

    def guarded(self, key):
        if self.size * 8 > 16 * 1024**2:
            raise AssertionError(f"read of {self.shape} before the guard")
        return original(self, key)

    monkeypatch.setattr(h5py.Dataset, "__getitem__", guarded)


def test_h5_declaring_10_million_rows_with_nothing_written_is_refused_unread(
    tmp_path, capsys, no_large_reads
):
    """The reported case: an 8-KB file declaring 10 000 000 x 19 chunks never written was
    'valid' after 16 s and 5 GB."""
    path = tmp_path / "bomb.h5"
    with _h5(path, skip="acceleration") as handle:
        handle.create_dataset("acceleration", shape=(10_000_000, 19), dtype="f8", chunks=(1000, 19))
    assert path.stat().st_size < 64 * 1024
    started = time.perf_counter()
    assert _run(["validate", "accelerations", path]) == 1
    elapsed = time.perf_counter() - started
    err = capsys.readouterr().err
    assert "declares 10000000x19 values (1.52 GB) but the file stores 0 bytes" in err, err
    assert "before the guard" not in err and len(err.strip().splitlines()) == 1
    assert elapsed < 5.0  # refused from the header; reading would take tens of seconds


def test_mat73_declaring_more_than_it_stores_is_refused_unread(tmp_path, no_large_reads):
    path = tmp_path / "bomb.mat"
    with h5py.File(path, "w") as mat:
        mat.create_dataset("acceleration", shape=(19, 40_000_000), dtype="f8", chunks=(19, 1000))
        mat["sampling_rate_hz"] = np.array([[RATE_HZ]])
        mat["start_time"] = np.array([ord(c) for c in START], dtype="u2")
        mat["channels"] = np.array([[ord("a")]], dtype="u2")
    with pytest.raises(ContractError, match=r"variable acceleration declares 19x40000000"):
        read_accelerations(path)


def test_memory_budget_is_one_overridable_limit(tmp_path, monkeypatch):
    import scipy.io

    assert max_array_bytes() == DEFAULT_MAX_ARRAY_BYTES == 4 * 1024**3
    monkeypatch.setenv(MAX_ARRAY_BYTES_VARIABLE, "8G")
    assert max_array_bytes() == 8 * 1024**3
    monkeypatch.setenv(MAX_ARRAY_BYTES_VARIABLE, "lots")
    with pytest.raises(ValueError, match=MAX_ARRAY_BYTES_VARIABLE):
        max_array_bytes()
    # 7680 x 4 float64 = 245.76 KB: within the default budget, above a 100-KB one, in
    # every container format
    data = response(N_SAMPLES, 1)
    with _h5(tmp_path / "a.h5", data=data):
        pass
    scipy.io.savemat(
        tmp_path / "a.mat",
        {"data": data, "fs": RATE_HZ, "t0": START, "chanNames": np.array(CHANNELS, dtype=object)},
    )
    from data_contracts import AccelerationRecord, write_accelerations

    write_accelerations(AccelerationRecord(data, RATE_HZ, START, CHANNELS), tmp_path / "a.npz")
    monkeypatch.delenv(MAX_ARRAY_BYTES_VARIABLE)
    for name in ("a.h5", "a.mat", "a.npz"):
        assert read_accelerations(tmp_path / name).acceleration.shape == (N_SAMPLES, 4)
    monkeypatch.setenv(MAX_ARRAY_BYTES_VARIABLE, "100K")
    for name in ("a.h5", "a.mat", "a.npz"):
        with pytest.raises(ContractError) as caught:
            read_accelerations(tmp_path / name)
        message = str(caught.value)
        assert f"{N_SAMPLES}x4 values (246 KB as float64)" in message.replace("4x7680", "7680x4")
        assert "memory budget of 102 KB" in message and MAX_ARRAY_BYTES_VARIABLE in message


def test_npz_small_array_claiming_billions_is_refused_before_loading(tmp_path):
    """Every array of an .npz goes through the guard, not only the samples: a channels
    header claiming 10^10 names in a 1-KB archive (np.load would allocate them first)."""
    import zipfile

    from workbench.signals.block_plan import read_file_info

    path = tmp_path / "names.npz"
    arrays = {
        "acceleration": response(64, 1),
        "sampling_rate_hz": np.float64(RATE_HZ),
        "start_time": np.str_(START),
    }
    with zipfile.ZipFile(path, "w") as archive:
        for key, value in arrays.items():
            with archive.open(f"{key}.npy", "w") as handle:
                np.lib.format.write_array(handle, np.asarray(value))
        with archive.open("channels.npy", "w") as handle:
            header = {"descr": "<U5", "fortran_order": False, "shape": (10**10,)}
            np.lib.format.write_array_header_1_0(handle, header)
            handle.write(np.array(CHANNELS, dtype="<U5").tobytes())
    for read in (read_accelerations, read_file_info):
        with pytest.raises(ContractError, match="array channels declares 10000000000 values"):
            read(path)


def test_csv_with_too_many_columns_is_refused_before_parsing(tmp_path, capsys, monkeypatch):
    """The reported case: 10^6 columns ran 147 s, then MemoryError (10^5: 101 s)."""
    import data_contracts.formats.text as text

    def no_parse(*args, **kwargs):
        raise AssertionError("parsed before the column count was checked")

    monkeypatch.setattr(text, "read_delimited", no_parse)
    n = MAX_CHANNELS + 1
    path = tmp_path / "wide.csv"
    header = "time," + ",".join(f"c{j}" for j in range(n))
    rows = [f"2026-03-01T00:00:{i:02d}Z," + ",".join(["0.1"] * n) for i in range(3)]
    path.write_text("\n".join([header, *rows]) + "\n")
    assert _run(["validate", "accelerations", path]) == 1
    err = capsys.readouterr().err
    assert f"the header line has {n} channels; an acceleration file has at most 1024" in err
    assert len(err.strip().splitlines()) == 1


# ---------------------------------------------------------------------- option ranges
@pytest.fixture(scope="module")
def voyage(tmp_path_factory) -> Path:
    from .voyage import write_voyage

    folder = tmp_path_factory.mktemp("voyage")
    write_voyage(folder, n_files=4)
    return folder


OPTION_CASES = {
    "max order 1e12": (["--max-order", "1000000000000"], "--max-order 1000000000000 is above"),
    "lscf max order 1e12": (
        ["--method", "lscf", "--lscf-max-order", "1000000000000"],
        "--lscf-max-order 1000000000000 is above",
    ),
    "step 0.0001 min": (
        ["--step-minutes", "0.0001"],
        "--step-minutes 0.0001 puts every sample in 2e+04 blocks of 2 min; at most 100: "
        "give --step-minutes of at least 0.02",
    ),
}


@pytest.mark.parametrize(("extra", "fragment"), list(OPTION_CASES.values()), ids=list(OPTION_CASES))
def test_option_ranges_are_usage_errors_before_anything_is_built(
    voyage, tmp_path, capsys, extra, fragment
):
    argv = ["identify", voyage, "--out", tmp_path / "out", *IDENTIFY_ARGS, *extra]
    assert _run(argv) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_max_order_from_a_config_is_checked_too(voyage, tmp_path, capsys):
    config = tmp_path / "ship.toml"
    config.write_text("[identify]\nmax_order = 1000000000000\n", encoding="utf-8")
    argv = ["identify", voyage, "--out", tmp_path / "out", *IDENTIFY_ARGS]
    argv = [a for a in argv if a != "--max-order" and a != "16"]  # the config's order
    assert _run([*argv, "--config", config]) == 2
    err = capsys.readouterr().err
    assert "[identify] max_order = 1000000000000 must be at most 2000" in err, err


def test_library_options_refuse_huge_ranges_without_building_them():
    from workbench.errors import OptionError
    from workbench.identification import IdentifyOptions

    with pytest.raises(OptionError) as caught:
        IdentifyOptions(orders=range(2, 10**12, 2))  # a tuple of it would not fit in memory
    assert "orders: 499999999999 orders given; orders lie in 1..2000" in str(caught.value)
    with pytest.raises(OptionError) as caught:
        IdentifyOptions(lscf_orders=range(1, 10**12))
    assert "lscf_orders" in str(caught.value)
    with pytest.raises(OptionError) as caught:
        IdentifyOptions(step_s=0.006)
    assert "at least 12 s" in str(caught.value)


def test_plan_of_absurdly_many_blocks_is_refused_before_listing():
    import pandas as pd

    from workbench.blocks import BlockGrid
    from workbench.errors import OptionError
    from workbench.signals.block_plan import FileInfo, plan_file_infos

    # 60 days in one file's header, 1-s blocks every second: 5.2 million blocks
    info = FileInfo(Path("x.npz"), pd.Timestamp(START), 1.0, 60 * 86400, CHANNELS)
    grid = BlockGrid(pd.Timestamp(START), 1.0, 1.0)
    started = time.perf_counter()
    with pytest.raises(OptionError) as caught:
        plan_file_infos([info], grid)
    assert time.perf_counter() - started < 1.0
    assert "about 5.18e+06 blocks" in str(caught.value) and "at most 1000000" in str(caught.value)


# ---------------------------------------------------------------------- UFF records
def _write_uff(path: Path, data: np.ndarray) -> None:
    pyuff = pytest.importorskip("pyuff")
    zeros = dict.fromkeys(
        (
            "ver_num",
            "load_case_id",
            "ref_node",
            "ref_dir",
            "abscissa_len_unit_exp",
            "abscissa_force_unit_exp",
            "abscissa_temp_unit_exp",
            "ordinate_force_unit_exp",
            "ordinate_temp_unit_exp",
            "orddenom_spec_data_type",
            "orddenom_len_unit_exp",
            "orddenom_force_unit_exp",
            "orddenom_temp_unit_exp",
            "z_axis_spec_data_type",
            "z_axis_len_unit_exp",
            "z_axis_force_unit_exp",
            "z_axis_temp_unit_exp",
        ),
        0,
    )
    sets = [
        pyuff.prepare_58(
            binary=0,
            id1="Time response",
            id2="",
            id3="",
            id4="2026-03-01 00:00:00",
            id5="",
            func_type=1,
            rsp_node=101 + j,
            rsp_dir=3,
            abscissa_spacing=1,
            abscissa_min=0.0,
            abscissa_inc=1.0 / RATE_HZ,
            ordinate_spec_data_type=12,
            ordinate_axis_units_lab="m/s^2",
            ord_data_type=4,
            num_pts=len(data),
            rsp_ent_name="pt",
            ref_ent_name="NONE",
            z_axis_value=0.0,
            ordinate_len_unit_exp=1,
            orddenom_axis_units_lab="NONE",
            z_axis_axis_units_lab="NONE",
            abscissa_spec_data_type=17,
            abscissa_axis_units_lab="s",
            data=data[:, j],
            x=np.arange(len(data)) / RATE_HZ,
            **zeros,
        )
        for j in range(data.shape[1])
    ]
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")


@pytest.fixture(scope="module")
def uff_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("uff") / "whole.uff"
    _write_uff(path, response(64, 1))
    return path


def test_whole_uff_is_valid(uff_file):
    record = read_accelerations(uff_file)
    assert record.acceleration.shape == (64, 4) and record.sampling_rate_hz == RATE_HZ


@pytest.mark.parametrize("fraction", [0.3, 0.5, 0.55, 0.8, 0.99])
def test_uff_cut_inside_a_record_is_refused(uff_file, tmp_path, fraction):
    """Cut in half (inside the third record's header) and elsewhere: pyuff alone drops the
    unfinished record and reads 2 of the 4 channels."""
    raw = uff_file.read_bytes()
    record_length = len(raw) // 4  # four records of the same size
    cut = int(len(raw) * fraction)
    if cut % record_length < 20:
        cut += 40  # into the next record's header: a cut at a boundary is a valid file
    path = tmp_path / "cut.uff"
    path.write_bytes(raw[:cut])
    with pytest.raises(ContractError, match="the file ends inside a record"):
        read_accelerations(path)


def _edit_uff(uff_file: Path, tmp_path: Path, old: str, new: str) -> Path:
    text = uff_file.read_text()
    assert old in text
    path = tmp_path / "edited.uff"
    path.write_text(text.replace(old, new))
    return path


def test_uff_declared_length_must_equal_the_data(uff_file, tmp_path):
    # record header line 7: ordinate type (10 columns), then the number of points
    path = _edit_uff(uff_file, tmp_path, "         4        64", "         42000000000")
    with pytest.raises(ContractError, match="declares 2000000000 points but holds 64"):
        read_accelerations(path)


def test_uff_zero_increment_is_refused(uff_file, tmp_path):
    path = _edit_uff(uff_file, tmp_path, "3.12500e-02", "0.00000e+00")
    with pytest.raises(ContractError, match="abscissa increment 0 s is not a positive time step"):
        read_accelerations(path)


def test_uff_of_two_samples_is_refused(tmp_path):
    path = tmp_path / "two.uff"
    _write_uff(path, response(2, 1))
    with pytest.raises(ContractError, match="holds 2 samples; a time response needs at least 16"):
        read_accelerations(path)


# ---------------------------------------------------------------------- messages
def test_control_characters_in_file_names_are_escaped(tmp_path, capsys):
    name = "rec\x1b]0;owned\x07\x1b[31m\u202e.npz"
    (tmp_path / name).write_bytes(b"not an archive")
    assert _run(["validate", "accelerations", tmp_path / name]) == 1
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\x07" not in err and "\u202e" not in err
    assert r"rec\x1b]0;owned\x07\x1b[31m\u202e.npz" in err
    assert len(err.strip().splitlines()) == 1
    # a usage error quoting a path, too
    assert _run(["track", tmp_path / name, "--out", tmp_path / "t\x1b[2J.txt"]) == 2
    err = capsys.readouterr().err
    assert "\x1b" not in err and r"t\x1b[2J.txt" in err


@pytest.mark.parametrize(
    "content",
    [b"garbage", np.random.default_rng(0).bytes(3000), b"PK\x03\x04 truncated"],
    ids=["text", "random", "zip header"],
)
def test_garbage_npz_is_one_plain_line(tmp_path, capsys, content):
    path = tmp_path / "garbage.npz"
    path.write_bytes(content)
    assert _run(["validate", "accelerations", path]) == 1
    err = capsys.readouterr().err
    assert err.strip() == (
        f"{path}: not a valid .npz acceleration file (a NumPy archive of the numeric arrays "
        "acceleration, sampling_rate_hz, start_time and channels)"
    )
    assert "pickle" not in err.replace(str(path), "")
