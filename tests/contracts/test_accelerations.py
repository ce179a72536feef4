"""Acceleration files: canonical .npz, MATLAB v5 and v7.3, CSV; every kind of bad record."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import scipy.io

from data_contracts import (
    AccelerationRecord,
    ContractError,
    read_accelerations,
    write_accelerations,
)

START = pd.Timestamp("2026-03-01T12:05:00Z")


def record(n_samples: int = 640, n_channels: int = 3) -> AccelerationRecord:
    rng = np.random.default_rng(0)
    data = rng.normal(scale=0.05, size=(n_samples, n_channels))
    data[10:20, 1] = np.nan
    return AccelerationRecord(
        data, 64.0, START, tuple(f"acc{j:02d}" for j in range(1, n_channels + 1))
    )


def test_npz_round_trip_keeps_nan_and_time(tmp_path):
    original = record()
    back = read_accelerations(write_accelerations(original, tmp_path / "a.npz"))
    np.testing.assert_array_equal(back.acceleration, original.acceleration)
    assert back.sampling_rate_hz == 64.0
    assert back.start_time == START
    assert back.channels == original.channels
    assert back.end_time == START + pd.Timedelta(seconds=10)


def test_mat_v5_with_custom_variable_names_and_channels_first(tmp_path):
    original = record()
    path = tmp_path / "a.mat"
    scipy.io.savemat(
        path,
        {
            "acc": original.acceleration.T,
            "fs": 64.0,
            "t0": "2026-03-01T12:05:00Z",
            "names": np.array(original.channels, dtype=object),
        },
    )
    back = read_accelerations(
        path,
        mat_variables={
            "acceleration": "acc",
            "sampling_rate_hz": "fs",
            "start_time": "t0",
            "channels": "names",
        },
    )
    np.testing.assert_array_equal(back.acceleration, original.acceleration)
    assert back.channels == original.channels and back.start_time == START


def test_mat_v73_hdf5(tmp_path):
    h5py = pytest.importorskip("h5py")
    original = record()
    path = tmp_path / "a.mat"
    with h5py.File(path, "w", userblock_size=512) as mat:
        # MATLAB stores column-major: a samples x channels matrix appears transposed
        mat["acceleration"] = original.acceleration.T
        mat["sampling_rate_hz"] = np.array([[64.0]])
        mat["start_time"] = np.array([ord(c) for c in "2026-03-01T12:05:00Z"], dtype=np.uint16)
        refs = []
        for name in original.channels:
            mat[f"#refs#/{name}"] = np.array([ord(c) for c in name], dtype=np.uint16)
            refs.append(mat[f"#refs#/{name}"].ref)
        mat.create_dataset("channels", data=np.array(refs, dtype=h5py.ref_dtype))
    with open(path, "r+b") as handle:
        handle.write(b"MATLAB 7.3 MAT-file".ljust(128, b" "))
    back = read_accelerations(path)
    np.testing.assert_array_equal(back.acceleration, original.acceleration)
    assert back.channels == original.channels and back.start_time == START


def test_csv_rate_from_time_column(tmp_path):
    original = record(n_samples=128)
    times = START + pd.to_timedelta(np.arange(128) / 64.0, unit="s")
    frame = pd.DataFrame(original.acceleration, columns=list(original.channels))
    frame.insert(0, "time", times.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))
    path = tmp_path / "a.csv"
    frame.to_csv(path, index=False)
    back = read_accelerations(path)
    assert back.sampling_rate_hz == 64.0
    np.testing.assert_allclose(back.acceleration, original.acceleration, rtol=1e-15)


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"sampling_rate_hz": 0.0}, "column .sampling_rate_hz.: must be a positive number"),
        ({"channels": ("a", "b")}, "2 names for 3 columns"),
        ({"channels": ("a", "a", "b")}, "channel names must be unique"),
        ({"start_time": "not a time"}, "column .start_time.: not an ISO-8601 time"),
        ({"acceleration": np.ones(10)}, "must be 2-D"),
        ({"acceleration": np.full((10, 3), 9810.0)}, "must be in m/s²"),
    ],
)
def test_invalid_records_are_rejected(tmp_path, change, reason):
    fields = {**record().__dict__, **change}
    with pytest.raises(ContractError, match=reason):
        write_accelerations(AccelerationRecord(**fields), tmp_path / "bad.npz")
    assert not (tmp_path / "bad.npz").exists()


def test_unreadable_and_incomplete_files(tmp_path):
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"garbage")
    with pytest.raises(ContractError, match="broken.npz: not a valid .npz"):
        read_accelerations(broken)
    partial = tmp_path / "partial.npz"
    np.savez(partial, acceleration=np.zeros((4, 2)))
    with pytest.raises(ContractError) as caught:
        read_accelerations(partial)
    assert len(caught.value.violations) == 3
    (tmp_path / "x.wav").write_bytes(b"RIFF")
    with pytest.raises(ContractError, match="unknown acceleration format"):
        read_accelerations(tmp_path / "x.wav")


def test_pickled_npz_is_refused(tmp_path):
    path = tmp_path / "pickled.npz"
    np.savez(
        path,
        acceleration=np.array([{"evil": 1}], dtype=object),
        sampling_rate_hz=64.0,
        start_time="2026-01-01T00:00Z",
        channels=np.array(["a"]),
    )
    with pytest.raises(ContractError, match="not a valid .npz") as caught:
        read_accelerations(path)
    assert "pickle" not in " ".join(v.reason for v in caught.value.violations)


@pytest.mark.parametrize("order", ["C", "F"])
def test_one_pass_peaks_equal_the_per_column_definition(order):
    """``_column_peaks`` (one pass: wide rows for a C-ordered array, row chunks otherwise)
    against max |a| over the non-NaN samples per column (0 for a dead column, inf where an
    infinite value is), across chunk edges and in the rows left over by the wide view."""
    from data_contracts import accelerations

    rng = np.random.default_rng(3)
    n_rows = 3 * accelerations._PEAK_CHUNK_VALUES // 19 + 7  # several chunks and a rest
    assert n_rows % (accelerations._PEAK_ROW_VALUES // 19) > 1  # rows left over
    x = rng.standard_normal((n_rows, 19))
    x[rng.random(x.shape) < 0.01] = np.nan
    x[:, 4] = np.nan  # dead channel
    x[n_rows - 1, 7] = -np.inf  # in the last, partial chunk
    x[accelerations._PEAK_CHUNK_VALUES // 19, 11] = 42.0  # first row of the second chunk
    x[n_rows - 2, 12] = -17.0  # a negative peak among the rows left over
    x[5, 13] = -np.inf  # in the wide rows
    x = np.asarray(x, order=order)
    peaks = accelerations._column_peaks(x)
    expected = np.where(np.isnan(x), 0.0, np.abs(x)).max(axis=0)
    np.testing.assert_array_equal(peaks, expected)
    assert peaks[4] == 0.0 and peaks[7] == np.inf and peaks[11] == 42.0
    assert peaks[12] == 17.0 and peaks[13] == np.inf


def test_infinite_and_implausible_channels_are_named(tmp_path):
    x = np.zeros((50_000, 3))
    x[49_999, 1] = np.inf
    x[123, 2] = -600.0
    bad = AccelerationRecord(x, 64.0, START, ("a", "b", "c"))
    with pytest.raises(ContractError) as caught:
        write_accelerations(bad, tmp_path / "bad.npz")
    text = str(caught.value)
    assert "infinite values in channel(s) b" in text
    assert "above 500 m/s² in channel(s) c:" in text


@pytest.mark.parametrize("layout", ["C", "F", "big-endian", "float32", "compressed"])
def test_npz_samples_read_in_place_equal_numpy_load(tmp_path, layout):
    """The uncompressed member is read straight into its array (its CRC-32 checked);
    every layout gives what ``np.load`` gives, a compressed member is read by np.load."""
    data = record(n_samples=1000, n_channels=4).acceleration
    if layout == "F":
        data = np.asfortranarray(data)
    elif layout == "big-endian":
        data = data.astype(">f8")
    elif layout == "float32":
        data = data.astype(np.float32)
    path = tmp_path / "a.npz"
    save = np.savez_compressed if layout == "compressed" else np.savez
    save(
        path,
        acceleration=data,
        sampling_rate_hz=np.float64(64.0),
        start_time=np.str_("2026-03-01T12:05:00Z"),
        channels=np.array(["a", "b", "c", "d"]),
    )
    with np.load(path) as stored:
        expected = stored["acceleration"].astype(float)
    np.testing.assert_array_equal(read_accelerations(path).acceleration, expected)


def test_npz_with_a_damaged_sample_is_refused(tmp_path):
    """A flipped byte among the samples fails the member's CRC-32, as zipfile checks it."""
    path = write_accelerations(record(), tmp_path / "a.npz")
    raw = bytearray(path.read_bytes())
    position = raw.index(b"acceleration.npy") + 200  # inside the samples
    raw[position] ^= 0x40
    path.write_bytes(bytes(raw))
    with pytest.raises(ContractError, match="not a valid .npz acceleration file"):
        read_accelerations(path)
