"""Declared readers of dataset.yaml (imucal.io.readers): every option on small files written here."""

from __future__ import annotations

import json
import math
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from scipy import io as sio

from imucal import io
from imucal.columns import ACC, GYR, MAG, SEQ, TIME
from imucal.ingest import ingest_recording, summarize_recording
from imucal.io.dataset import read_dataset
from imucal.io.readers import DeclarationError, axis_matrix
from imucal.segments.filtering import find_contiguous_blocks, lowpass_recording
from imucal.segments.segmentation import segment_dataset

G = 9.80665
RNG = np.random.default_rng(7)
# 20 samples of acc (g) and gyr (deg/s) with distinct values per axis
N = 20
ACC_G = RNG.normal(0, 1, (N, 3)).round(4)
GYR_DPS = RNG.normal(0, 50, (N, 3)).round(3)


def write_dataset(folder: Path, recordings: dict, **extra) -> Path:
    """dataset.yaml with the given recordings (and extra top-level keys) in ``folder``."""
    cfg = {"name": "t", "gravity_m_s2": 9.81, "recordings": recordings, **extra}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "dataset.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    return folder


def ingest(folder: Path, name: str):
    dataset = read_dataset(folder)
    return ingest_recording(dataset.recordings[name], name, dataset, "test")


def csv_text(delimiter: str, header: bool = True, skip: tuple[str, ...] = ()) -> str:
    sep = " " if delimiter == "whitespace" else delimiter
    lines = list(skip)
    if header:
        lines.append(sep.join(["time", "ax", "ay", "az", "gx", "gy", "gz"]))
    for k in range(N):
        cells = [f"{0.01 * k:.2f}", *map(str, ACC_G[k]), *map(str, GYR_DPS[k])]
        lines.append(("   " if delimiter == "whitespace" else "") + sep.join(cells))
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# Table reader


@pytest.mark.parametrize("delimiter", [",", ";", "\t", "whitespace"])
def test_table_delimiters_names_units(tmp_path, delimiter):
    (tmp_path / "d.txt").write_text(csv_text(delimiter))
    entry = {
        "reader": "table",
        "file": "d.txt",
        "delimiter": delimiter,
        "columns": {
            "t_s": "time",
            "acc_x": "ax",
            "acc_y": "ay",
            "acc_z": "az",
            "gyr_x": "gx",
            "gyr_y": "gy",
            "gyr_z": "gz",
        },
        "units": {"acc": "g", "gyr": "deg/s"},
    }
    table, meta = ingest(write_dataset(tmp_path, {"poses": entry}), "poses")
    np.testing.assert_allclose(table[list(ACC)].to_numpy(), ACC_G * G, rtol=1e-15)
    np.testing.assert_allclose(table[list(GYR)].to_numpy(), np.deg2rad(GYR_DPS), rtol=1e-15)
    np.testing.assert_allclose(table[TIME].to_numpy(), 0.01 * np.arange(N))
    assert list(table.columns) == [TIME, *ACC, *GYR]  # no seq, no mag: absent, not NaN
    assert meta["sensors"] == ["acc", "gyr"] and meta["has_seq"] is False
    assert meta["source_units"] == {"acc": "g", "gyr": "deg/s"}
    assert meta["files"][0]["sha256"] == io.sha256_file(tmp_path / "d.txt")
    assert meta["units"][ACC[0]] == "m/s^2" and meta["units"][GYR[0]] == "rad/s"


def test_table_without_header_by_index_skip_lines_and_rate(tmp_path):
    (tmp_path / "d.csv").write_text(csv_text(",", header=False, skip=("Fs,100", "note,1")))
    entry = {"reader": "table", "file": "d.csv", "header": False, "skip_lines": 2,
             "columns": {"acc_x": 3, "acc_y": 2, "acc_z": 1}, "rate_hz": 50.0,
             "units": {"acc": "m/s^2"}}  # fmt: skip
    table, _ = ingest(write_dataset(tmp_path, {"static": entry}), "static")
    np.testing.assert_allclose(table[list(ACC)].to_numpy(), ACC_G[:, ::-1])
    np.testing.assert_allclose(table[TIME].to_numpy(), np.arange(N) / 50.0)


def test_time_column_as_sample_counter_and_sort_by_time(tmp_path):
    rows = ["n,acc_x,acc_y,acc_z,part"] + [
        f"{k},{k},0,1,{'b' if k >= 5 else 'a'}" for k in range(10)
    ]
    (tmp_path / "d.csv").write_text("\n".join([rows[0], *rows[6:], *rows[1:6]]) + "\n")
    entry = {"reader": "table", "file": "d.csv", "columns": {"t_s": "n", "acc_x": "acc_x",
             "acc_y": "acc_y", "acc_z": "acc_z"}, "rate_hz": 4.0, "units": {"acc": "m/s^2"}}  # fmt: skip
    folder = write_dataset(tmp_path, {"ferraris": entry})
    with pytest.raises(
        io.RawDataError,
        match=r"d.csv, line 7: t_s 0.0 s is earlier than 2.25 s on the row before \(1 such "
        r"step\(s\)\); expected non-decreasing time; .*declare .*recordings.ferraris"
        r".sort_by_time: true",
    ):
        ingest(folder, "ferraris")
    entry["sort_by_time"] = True
    table, meta = ingest(write_dataset(tmp_path, {"ferraris": entry}), "ferraris")
    np.testing.assert_array_equal(table[TIME].to_numpy(), np.arange(10) / 4.0)
    np.testing.assert_array_equal(table[ACC[0]].to_numpy(), np.arange(10))
    assert meta["sorted_by_time"] is True


@pytest.mark.parametrize(
    ("sensor", "unit", "value", "expected"),
    [
        ("acc", "m/s^2", 2.5, 2.5),
        ("acc", "g", 2.0, 2 * G),
        ("gyr", "rad/s", 0.3, 0.3),
        ("gyr", "deg/s", 90.0, math.pi / 2),
        ("gyr", "mrad/s", 250.0, 0.25),
        ("mag", "T", 4e-5, 0.8),
        ("mag", "uT", 40.0, 0.8),
        ("mag", "gauss", 0.4, 0.8),
        ("mag", "normalised", 0.9, 0.9),
    ],
)
def test_each_unit(tmp_path, sensor, unit, value, expected):
    cols = [f"{sensor}_{a}" for a in "xyz"]
    (tmp_path / "d.csv").write_text(
        ",".join(cols) + "\n" + "\n".join(f"{value},{-value},{2 * value}" for _ in range(3)) + "\n"
    )
    entry = {"reader": "table", "file": "d.csv", "columns": {c: c for c in cols},
             "rate_hz": 10, "units": {sensor: unit}}  # fmt: skip
    table, meta = ingest(write_dataset(tmp_path, {"tumble": entry}, field_norm_t=5e-5), "tumble")
    np.testing.assert_allclose(
        table[cols].to_numpy(), np.tile([expected, -expected, 2 * expected], (3, 1)), rtol=1e-12
    )
    assert meta["sensors"] == [sensor]


def test_counts_sensitivity_zero_counts_and_axes(tmp_path):
    raw = np.array([[32768 + 100, 32768 - 200, 32768 + 300]] * 4)
    (tmp_path / "d.txt").write_text("\n".join(" ".join(map(str, r)) for r in raw) + "\n")
    entry = {"reader": "table", "file": "d.txt", "delimiter": "whitespace", "header": False,
             "columns": {"gyr_x": 0, "gyr_y": 1, "gyr_z": 2}, "rate_hz": 100,
             "units": {"gyr": "counts"}, "sensitivity": {"gyr": 0.01},
             "zero_counts": {"gyr": 32768}, "axes": {"gyr": ["-y", "z", "x"]}}  # fmt: skip
    table, meta = ingest(write_dataset(tmp_path, {"static": entry}), "static")
    # source (1.0, -2.0, 3.0) rad/s; target x = -source y, y = source z, z = source x
    np.testing.assert_allclose(table[list(GYR)].to_numpy(), np.tile([2.0, 3.0, 1.0], (4, 1)))
    assert meta["sensitivity"] == {"gyr": 0.01}


def test_axis_matrix_is_a_signed_permutation():
    m = axis_matrix(["x", "-z", "y"])
    np.testing.assert_array_equal(m @ [1.0, 2.0, 3.0], [1.0, -3.0, 2.0])
    with pytest.raises(DeclarationError, match=r"k: \['x', 'x', 'z'\] uses a source axis twice"):
        axis_matrix(["x", "x", "z"], "k")


def test_magnetometer_in_counts_is_tesla_per_count_over_field_norm(tmp_path):
    (tmp_path / "m.csv").write_text("mx,my,mz\n6000,0,0\n0,-6000,0\n")
    entry = {"reader": "table", "file": "m.csv", "columns": {"mag_x": "mx", "mag_y": "my",
             "mag_z": "mz"}, "rate_hz": 50, "units": {"mag": "counts"},
             "sensitivity": {"mag": 1e-4 / 12000}}  # fmt: skip
    table, _ = ingest(write_dataset(tmp_path, {"tumble": entry}, field_norm_t=5e-5), "tumble")
    np.testing.assert_allclose(table[list(MAG)].to_numpy(), [[1.0, 0, 0], [0, -1.0, 0]])


# --------------------------------------------------------------------------------------------
# MATLAB and HDF5


def test_matlab_v5_array_and_vectors(tmp_path):
    data = np.column_stack([0.01 * np.arange(N), ACC_G])
    sio.savemat(tmp_path / "a.mat", {"buf": data, "tt": data[:, 0], "ax": data[:, 1],
                                     "ay": data[:, 2], "az": data[:, 3]})  # fmt: skip
    by_index = {"reader": "matlab", "file": "a.mat", "variable": "buf",
                "columns": {"t_s": 0, "acc_x": 1, "acc_y": 2, "acc_z": 3}, "units": {"acc": "g"}}  # fmt: skip
    by_name = {"reader": "matlab", "file": "a.mat",
               "columns": {"t_s": "tt", "acc_x": "ax", "acc_y": "ay", "acc_z": "az"},
               "units": {"acc": "g"}}  # fmt: skip
    folder = write_dataset(tmp_path, {"poses": by_index, "static": by_name})
    for name in ("poses", "static"):
        table, _ = ingest(folder, name)
        np.testing.assert_allclose(table[list(ACC)].to_numpy(), ACC_G * G, rtol=1e-15)
        np.testing.assert_allclose(table[TIME].to_numpy(), data[:, 0])


def test_matlab_v73_is_read_in_matlab_orientation(tmp_path):
    data = np.column_stack([0.01 * np.arange(N), GYR_DPS])
    with h5py.File(tmp_path / "g.mat", "w") as f:  # MATLAB v7.3 stores the transpose
        f["gyroBuffer"] = data.T
    entry = {"reader": "matlab", "file": "g.mat", "variable": "gyroBuffer",
             "columns": {"t_s": 0, "gyr_x": 1, "gyr_y": 2, "gyr_z": 3}, "units": {"gyr": "deg/s"}}  # fmt: skip
    table, _ = ingest(write_dataset(tmp_path, {"static": entry}), "static")
    np.testing.assert_allclose(table[list(GYR)].to_numpy(), np.deg2rad(GYR_DPS), rtol=1e-15)


def test_hdf5_paths_in_groups_transpose_and_vectors(tmp_path):
    data = np.column_stack([0.01 * np.arange(N), ACC_G])
    with h5py.File(tmp_path / "h.h5", "w") as f:
        f["imu/raw/acc"] = data.T  # 4 x N: needs transpose
        f["imu/t"] = data[:, 0]
        for k, a in enumerate("xyz"):
            f[f"imu/acc_{a}"] = data[:, k + 1]
    matrix = {"reader": "hdf5", "file": "h.h5", "dataset": "imu/raw/acc", "transpose": True,
              "columns": {"t_s": 0, "acc_x": 1, "acc_y": 2, "acc_z": 3}, "units": {"acc": "g"}}  # fmt: skip
    vectors = {"reader": "hdf5", "file": "h.h5", "units": {"acc": "g"},
               "columns": {"t_s": "/imu/t", "acc_x": "imu/acc_x", "acc_y": "imu/acc_y",
                           "acc_z": "imu/acc_z"}}  # fmt: skip
    folder = write_dataset(tmp_path, {"poses": matrix, "static": vectors})
    for name in ("poses", "static"):
        table, _ = ingest(folder, name)
        np.testing.assert_allclose(table[list(ACC)].to_numpy(), ACC_G * G, rtol=1e-15)
    matrix["columns"] = {**matrix["columns"], "acc_z": 4}
    with pytest.raises(DeclarationError, match=r"recordings.poses.columns.acc_z: column index 4 "
                       r"not in 'imu/raw/acc' of .*h.h5 \(shape \(20, 4\), transposed\)"):  # fmt: skip
        ingest(write_dataset(tmp_path, {"poses": matrix}), "poses")
    matrix["dataset"] = "imu/raw/ac"
    with pytest.raises(DeclarationError, match=r"recordings.poses.dataset: 'imu/raw/ac' not in "
                       r".*h.h5 \(datasets: imu/acc_x, .*imu/raw/acc, imu/t\)"):  # fmt: skip
        ingest(write_dataset(tmp_path, {"poses": matrix}), "poses")


def write_netcdf4(path: Path, *, time_units: str = "minutes since 2021-09-20 08:52:00") -> None:
    """A netCDF4-like file written by h5py: a CF time variable, (N, 3) sensor variables with
    units attributes and fill values, a packed temperature."""
    with h5py.File(path, "w") as f:
        f.attrs["_NCProperties"] = np.bytes_(b"version=2,netcdf=4.7.4,hdf5=1.12.0,")
        f["time"] = np.arange(N, dtype=np.int64)
        f["time"].attrs["units"] = np.bytes_(time_units.encode())
        acc = ACC_G * G
        acc[3] = -999.0  # the fill value: a row without an accelerometer sample
        f["acceleration"] = acc
        f["acceleration"].attrs["units"] = np.bytes_(b"m/s2")
        f["acceleration"].attrs["_FillValue"] = np.array([-999.0])
        f["angular_velocity"] = np.deg2rad(GYR_DPS) * 1e3
        f["angular_velocity"].attrs["units"] = np.bytes_(b"mrad/s")
        f["temperature"] = np.arange(N, dtype=np.int16) * 5 + 100
        f["temperature"].attrs["scale_factor"] = np.array([0.01])
        f["temperature"].attrs["add_offset"] = np.array([20.0])


def netcdf_entry() -> dict:
    return {
        "reader": "netcdf",
        "file": "c.nc",
        "columns": {"t_s": "time", **{f"acc_{a}": ["acceleration", k] for k, a in enumerate("xyz")},
                    **{f"gyr_{a}": ["angular_velocity", k] for k, a in enumerate("xyz")},
                    "temp_c": "temperature"},
        "units": {"acc": "m/s^2", "gyr": "mrad/s"},
    }  # fmt: skip


def test_netcdf4_time_units_fill_values_and_packing(tmp_path):
    write_netcdf4(tmp_path / "c.nc")
    table, meta = ingest(write_dataset(tmp_path, {"poses": netcdf_entry()}), "poses")
    # minutes since the origin -> seconds since it
    np.testing.assert_array_equal(table[TIME].to_numpy(), 60.0 * np.arange(N))
    expected = ACC_G * G
    expected[3] = np.nan
    np.testing.assert_allclose(table[list(ACC)].to_numpy(), expected, rtol=1e-15)
    np.testing.assert_allclose(table[list(GYR)].to_numpy(), np.deg2rad(GYR_DPS), rtol=1e-14)
    np.testing.assert_allclose(table["temp_c"].to_numpy(), 21.0 + 0.05 * np.arange(N), rtol=1e-12)
    assert meta["time_units"] == "minutes since 2021-09-20 08:52:00"
    assert meta["file_units"]["gyr_x"] == "mrad/s"


def test_netcdf4_refuses_a_unit_the_file_contradicts_and_a_plain_file(tmp_path):
    write_netcdf4(tmp_path / "c.nc")
    entry = {**netcdf_entry(), "units": {"acc": "m/s^2", "gyr": "rad/s"}}
    with pytest.raises(DeclarationError, match=r"recordings.poses.units.gyr: 'rad/s', but variable "
                       r"'angular_velocity' of .*c.nc says units 'mrad/s'; expected the file's "
                       r"unit \('mrad/s'\)"):  # fmt: skip
        ingest(write_dataset(tmp_path, {"poses": entry}), "poses")
    with pytest.raises(
        DeclarationError, match=r"recordings.poses.rate_hz: rate_hz beside the time"
    ):
        ingest(write_dataset(tmp_path, {"poses": {**netcdf_entry(), "rate_hz": 1.0}}), "poses")
    (tmp_path / "c.nc").unlink()
    (tmp_path / "c.nc").write_bytes(b"CDF\x01" + bytes(60))  # netCDF3 classic
    with pytest.raises(io.RawDataError, match=r"c.nc.*not an HDF5 file .*expected a netCDF4 file"):
        ingest(write_dataset(tmp_path, {"poses": netcdf_entry()}), "poses")


# --------------------------------------------------------------------------------------------
# Streams and parts


def stream_files(tmp_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """acc at 100 Hz (irregular receive times) and mag at 30 Hz, with two shared stamps."""
    t_acc = np.cumsum(np.r_[0.0, RNG.choice([0.002, 0.002, 0.026], 299)])
    t_mag = np.arange(0.001, t_acc[-1], 1 / 30.0)
    t_mag[[3, 7]] = t_acc[[40, 90]]  # exactly shared times share a row
    t_mag.sort()
    acc = np.column_stack([t_acc, np.tile([0.0, 0.0, 1.0], (t_acc.size, 1))])
    mag = np.column_stack([t_mag, np.tile([0.2, 0.0, -0.45], (t_mag.size, 1))])
    np.savetxt(tmp_path / "acc.txt", acc)
    with h5py.File(tmp_path / "mag.mat", "w") as f:
        f["compassBuffer"] = mag.T
    return t_acc, t_mag


def streams_entry() -> dict:
    return {
        "streams": [
            {"reader": "table", "file": "acc.txt", "delimiter": "whitespace", "header": False,
             "columns": {"t_s": 0, "acc_x": 1, "acc_y": 2, "acc_z": 3}, "units": {"acc": "g"}},
            {"reader": "matlab", "file": "mag.mat", "variable": "compassBuffer",
             "columns": {"t_s": 0, "mag_x": 1, "mag_y": 2, "mag_z": 3}, "units": {"mag": "gauss"}},
        ]
    }  # fmt: skip


def test_streams_merge_on_time_without_invented_samples(tmp_path):
    t_acc, t_mag = stream_files(tmp_path)
    table, meta = ingest(
        write_dataset(tmp_path, {"tumble": streams_entry()}, field_norm_t=5e-5), "tumble"
    )
    union = np.union1d(t_acc, t_mag)
    np.testing.assert_array_equal(table[TIME].to_numpy(), union)
    assert len(table) == t_acc.size + t_mag.size - 2  # the two shared stamps are one row each
    has_acc = table[ACC[0]].notna().to_numpy()
    has_mag = table[MAG[0]].notna().to_numpy()
    np.testing.assert_array_equal(table[TIME].to_numpy()[has_acc], t_acc)
    np.testing.assert_array_equal(table[TIME].to_numpy()[has_mag], t_mag)
    assert (has_acc & has_mag).sum() == 2
    np.testing.assert_allclose(
        table.loc[has_mag, list(MAG)].to_numpy(), [[0.4, 0.0, -0.9]] * t_mag.size
    )
    assert table.loc[~has_acc, list(ACC)].isna().all().all()  # NaN, never filled
    assert len(meta["files"]) == 2 and [s["sensors"] for s in meta["streams"]] == [["acc"], ["mag"]]
    summary = summarize_recording(table, meta)
    assert summary["samples"] == {"acc": t_acc.size, "mag": t_mag.size}
    assert summary["lost_packets"] is None and "no packet counter" in summary["notes"][0]
    assert summary["irregular"] is True  # median 2 ms, mean ~10 ms
    assert summary["non_increasing_steps"] == 0
    np.testing.assert_allclose(summary["effective_rate_hz"], len(table) / (union[-1] - union[0]))
    np.testing.assert_allclose(summary["dt_median_s"], np.median(np.diff(union)))
    # each sensor is low-pass filtered on its own samples; NaN rows stay NaN
    out = lowpass_recording(table, order=2, cutoff_hz=5.0)
    np.testing.assert_array_equal(out[MAG[0]].notna().to_numpy(), has_mag)
    np.testing.assert_allclose(out.loc[has_acc, ACC[2]].to_numpy(), G, rtol=1e-9)
    np.testing.assert_allclose(out.attrs["lowpass"]["sensors"]["mag"]["fs_hz"], 30.0, rtol=0.02)


def test_irregular_bursts_are_one_block_but_a_real_gap_splits():
    # 100 Hz delivered in bursts: 12 stamps 2 ms apart, then a pause (catch-up), never loss
    period = np.tile(np.r_[[0.002] * 11, 0.098], 50)
    t = np.cumsum(np.r_[0.0, period])
    assert find_contiguous_blocks(t) == [(0, t.size)]
    t[300:] += 2.0
    assert find_contiguous_blocks(t) == [(0, 300), (300, t.size)]


def test_parts_are_concatenated_with_a_gap(tmp_path):
    for k in range(2):
        (tmp_path / f"p{k}.csv").write_text(
            "t,ax,ay,az\n" + "\n".join(f"{0.01 * i:.2f},0,0,1" for i in range(30 + k)) + "\n"
        )
    part = {"reader": "table", "columns": {"t_s": "t", "acc_x": "ax", "acc_y": "ay",
            "acc_z": "az"}, "units": {"acc": "g"}}  # fmt: skip
    entry = {"parts": [{**part, "file": "p0.csv"}, {**part, "file": "p1.csv"}]}
    table, meta = ingest(write_dataset(tmp_path, {"rotation3d": entry}), "rotation3d")
    assert len(table) == 61
    p0, p1 = meta["parts"]
    assert (p0["start_row"], p0["end_row"], p1["start_row"], p1["end_row"]) == (0, 30, 30, 61)
    assert p1["t_start_s"] - p0["t_end_s"] == pytest.approx(10.0)  # PART_GAP_S
    assert find_contiguous_blocks(table[TIME].to_numpy()) == [(0, 30), (30, 61)]


# --------------------------------------------------------------------------------------------
# Section lists


def ferraris_table(tmp_path: Path) -> dict:
    rows = ["n,ax,ay,az,gx,gy,gz"] + [
        f"{k},{RNG.normal()},{RNG.normal()},{9.8 + RNG.normal()},0,0,{RNG.normal()}"
        for k in range(200)
    ]
    (tmp_path / "f.csv").write_text("\n".join(rows) + "\n")
    return {"reader": "table", "file": "f.csv", "rate_hz": 10.0,
            "columns": {"t_s": "n", "acc_x": "ax", "acc_y": "ay", "acc_z": "az",
                        "gyr_x": "gx", "gyr_y": "gy", "gyr_z": "gz"},
            "units": {"acc": "m/s^2", "gyr": "deg/s"}}  # fmt: skip


def test_sections_ferraris_json_by_sample_index(tmp_path):
    entry = ferraris_table(tmp_path)
    (tmp_path / "s.json").write_text(json.dumps({"x_p": {"start": 10, "end": 50},
                                                 "z_rot": {"start": 100, "end": 160}}))  # fmt: skip
    sections = {
        "recording": "ferraris",
        "file": "s.json",
        "format": "ferraris_json",
        "index": "sample",
    }
    folder = write_dataset(tmp_path, {"ferraris": entry}, sections=sections)
    table, meta = ingest(folder, "ferraris")
    x_p, z_rot = meta["sections"]
    # end exclusive: samples 10..49 -> 1.0 .. 4.9 s
    assert x_p == {"label": "x_p", "kind": "position", "up": "+x", "start_s": 1.0, "end_s": 4.9}
    assert z_rot["kind"] == "phase" and z_rot["axis"] == "z" and z_rot["angle_deg"] == 360.0
    assert read_dataset(folder).recording_files("ferraris")[-1] == tmp_path / "s.json"
    segments = segment_dataset(
        {"ferraris": table}, manual=[{"recording": "ferraris", **e} for e in meta["sections"]]
    )
    assert segments[["label", "start_index", "end_index", "up"]].values.tolist() == [
        ["x_p", 10, 50, "+x"], ["z_rot", 100, 160, ""]]  # fmt: skip
    assert segments["angle_deg"].tolist()[1] == 360.0


def test_sections_csv_by_time_and_unknown_label(tmp_path):
    entry = ferraris_table(tmp_path)
    (tmp_path / "s.csv").write_text("label,start,end,kind,axis\nturn,2.0,5.5,phase,y\nrest,6,9,,\n")
    sections = {"recording": "ferraris", "file": "s.csv", "format": "csv", "index": "time"}
    folder = write_dataset(tmp_path, {"ferraris": entry}, sections=sections)
    with pytest.raises(
        DeclarationError, match=r"sections.labels.rest: label 'rest' of .*s.csv has no meaning"
    ):
        ingest(folder, "ferraris")
    sections["labels"] = {"rest": {"kind": "static"}}
    _, meta = ingest(write_dataset(tmp_path, {"ferraris": entry}, sections=sections), "ferraris")
    assert meta["sections"] == [
        {"label": "turn", "start_s": 2.0, "end_s": 5.5, "kind": "phase", "axis": "y"},
        {"label": "rest", "start_s": 6.0, "end_s": 9.0, "kind": "static"},
    ]


def test_sections_from_column(tmp_path):
    labels = ["x_p"] * 30 + ["x_a"] * 40 + ["y_rot"] * 30
    rows = ["part,t,ax,ay,az"] + [f"{p},{0.1 * k:.1f},0,0,1" for k, p in enumerate(labels)]
    (tmp_path / "a.csv").write_text("\n".join(rows) + "\n")
    entry = {"reader": "table", "file": "a.csv", "columns": {"t_s": "t", "acc_x": "ax",
             "acc_y": "ay", "acc_z": "az"}, "units": {"acc": "g"}}  # fmt: skip
    sections = {"recording": "ferraris", "from_column": "part"}
    table, meta = ingest(
        write_dataset(tmp_path, {"ferraris": entry}, sections=sections), "ferraris"
    )
    assert "part" not in table.columns
    assert [(s["label"], s["start_s"], s["end_s"]) for s in meta["sections"]] == [
        ("x_p", 0.0, 2.9), ("x_a", 3.0, 6.9), ("y_rot", 7.0, 9.9)]  # fmt: skip
    assert meta["sections"][1]["up"] == "-x"


# --------------------------------------------------------------------------------------------
# Errors name the key and the column


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"columns": {"acc_x": "accx", "acc_y": "ay", "acc_z": "az"}},
         (r"dataset.yaml: recordings.static.columns.acc_x: column 'accx' not in .*d.csv "
          r"\(columns: time, ax, ay, az, gx, gy, gz\); expected a column of its header line")),
        ({"columns": {"acc_x": 9, "acc_y": "ay", "acc_z": "az"}},
         r"recordings.static.columns.acc_x: column index 9 not in .*d.csv \(7 columns"),
        ({"columns": {"acc_x": "ax", "acc_y": "ay"}},
         (r"recordings.static.columns.acc_z: acc has column\(s\) \['acc_x', 'acc_y'\] but not "
          r"\['acc_z'\]")),
        ({"units": {}}, r"recordings.static.units.acc: missing; expected one of \['m/s\^2', 'g', 'counts'\]"),
        ({"units": {"acc": "counts"}},
         r"recordings.static.sensitivity.acc: missing; expected a positive number of m/s\^2 per count"),
        ({"sensitivity": {"acc": 0.1}}, r"recordings.static.sensitivity.acc: sensitivity given for units.acc: g"),
        ({"axes": {"gyr": ["x", "y", "z"]}}, r"recordings.static.axes.gyr: gyr has a axes entry but no column"),
        ({"rate_hz": None, "columns": {"acc_x": "ax", "acc_y": "ay", "acc_z": "az"}},
         r"recordings.static.rate_hz: no t_s column and no rate_hz"),
    ],
)  # fmt: skip
def test_bad_mappings_name_key_and_column(tmp_path, change, message):
    (tmp_path / "d.csv").write_text(csv_text(","))
    entry = {"reader": "table", "file": "d.csv", "rate_hz": 100,
             "columns": {"acc_x": "ax", "acc_y": "ay", "acc_z": "az"}, "units": {"acc": "g"}}  # fmt: skip
    entry.update(change)
    entry = {k: v for k, v in entry.items() if v is not None}
    with pytest.raises(DeclarationError, match=message):
        ingest(write_dataset(tmp_path, {"static": entry}), "static")


def test_header_false_refuses_names_and_bad_cells_name_the_line(tmp_path):
    (tmp_path / "d.csv").write_text(csv_text(",", header=False))
    entry = {"reader": "table", "file": "d.csv", "header": False, "rate_hz": 10,
             "columns": {"acc_x": "ax", "acc_y": 1, "acc_z": 2}, "units": {"acc": "g"}}  # fmt: skip
    with pytest.raises(
        DeclarationError, match=r"columns.acc_x: column 'ax' by name, but header is false"
    ):
        ingest(write_dataset(tmp_path, {"static": entry}), "static")
    text = csv_text(",").splitlines()
    text[4] = text[4].replace(text[4].split(",")[2], "1.2x", 1)
    (tmp_path / "d.csv").write_text("\n".join(text) + "\n")
    entry.update(header=True, columns={"acc_x": "ax", "acc_y": "ay", "acc_z": "az"})
    with pytest.raises(
        io.RawDataError, match=r"d.csv, line 5: column 'ay' holds '1.2x'; expected a number"
    ):
        ingest(write_dataset(tmp_path, {"static": entry}), "static")


def test_schema_and_structure_errors(tmp_path):
    (tmp_path / "d.csv").write_text(csv_text(","))
    entry = {"reader": "table", "file": "d.csv", "delimiter": "|", "rate_hz": 1,
             "columns": {"acc_x": "ax", "acc_y": "ay", "acc_z": "az"}, "units": {"acc": "g"}}  # fmt: skip
    with pytest.raises(ValueError, match=r"key 'recordings/static/delimiter': '\|' is not one of"):
        read_dataset(write_dataset(tmp_path, {"static": entry}))
    entry.pop("delimiter")
    both = {**entry, "streams": [entry]}
    with pytest.raises(ValueError, match=r"recordings.static: has \['file', 'streams'\]"):
        read_dataset(write_dataset(tmp_path, {"static": both}))
    with pytest.raises(
        ValueError, match=r"key 'sensitivity': required because recordings.cube is a native"
    ):
        read_dataset(write_dataset(tmp_path, {"cube": "cube.csv"}))
    mag = {"reader": "table", "file": "d.csv", "rate_hz": 1, "units": {"mag": "gauss"},
           "columns": {"mag_x": "ax", "mag_y": "ay", "mag_z": "az"}}  # fmt: skip
    with pytest.raises(DeclarationError, match=r"recordings.tumble.units.mag: the magnetometer in 'gauss' but "
                       r"dataset.yaml has no field_norm_t"):  # fmt: skip
        ingest(write_dataset(tmp_path, {"tumble": mag}), "tumble")


def test_missing_shared_file_names_the_key(tmp_path):
    entry = {"reader": "table", "file": "../absent/x.csv", "rate_hz": 1,
             "columns": {"acc_x": 0, "acc_y": 1, "acc_z": 2}, "units": {"acc": "g"}}  # fmt: skip
    with pytest.raises(
        FileNotFoundError, match=r"recordings.static.file: .*absent/x.csv not found"
    ):
        ingest(write_dataset(tmp_path / "ds", {"static": entry}), "static")


def test_seq_in_a_declared_table_is_checked(tmp_path):
    rows = ["t,seq,ax,ay,az"] + [f"{0.01 * k:.2f},{k if k != 5 else 4},0,0,1" for k in range(10)]
    (tmp_path / "d.csv").write_text("\n".join(rows) + "\n")
    entry = {"reader": "table", "file": "d.csv", "units": {"acc": "g"},
             "columns": {"t_s": "t", SEQ: "seq", "acc_x": "ax", "acc_y": "ay", "acc_z": "az"}}  # fmt: skip
    with pytest.raises(io.RawDataError, match=r"d.csv, line 7: seq 4 repeats the seq of line 6"):
        ingest(write_dataset(tmp_path, {"static": entry}), "static")


def test_time_vector_beside_columns_of_2d_arrays(tmp_path):
    """A 1 x N time variable beside 3 x N sensor arrays (MATLAB v5 and HDF5), no transpose."""
    t = 0.01 * np.arange(N) + 0.5
    sio.savemat(tmp_path / "r.mat", {"MATLABtime": t[None, :], "SENSacc": ACC_G.T,
                                     "SENSgyr": GYR_DPS.T})  # fmt: skip
    with h5py.File(tmp_path / "r.h5", "w") as f:
        f["time"] = t
        f["imu/acc"] = ACC_G  # N x 3
        f["imu/gyr"] = GYR_DPS.T  # 3 x N
    arrays = {"reader": "matlab", "file": "r.mat", "units": {"acc": "g", "gyr": "deg/s"},
              "columns": {"t_s": "MATLABtime", **{f"acc_{a}": ["SENSacc", k] for k, a in
                          enumerate("xyz")}, **{f"gyr_{a}": ["SENSgyr", k] for k, a in
                          enumerate("xyz")}}}  # fmt: skip
    variable = {"reader": "matlab", "file": "r.mat", "variable": "SENSacc", "transpose": True,
                "columns": {"t_s": "MATLABtime", "acc_x": 0, "acc_y": 1, "acc_z": 2},
                "units": {"acc": "g"}}  # fmt: skip
    hdf5 = {"reader": "hdf5", "file": "r.h5", "units": {"acc": "g", "gyr": "deg/s"},
            "columns": {"t_s": "time", **{f"acc_{a}": ["imu/acc", k] for k, a in
                        enumerate("xyz")}, **{f"gyr_{a}": ["imu/gyr", k] for k, a in
                        enumerate("xyz")}}}  # fmt: skip
    folder = write_dataset(tmp_path, {"poses": arrays, "static": variable, "tumble": hdf5})
    for name in ("poses", "static", "tumble"):
        table, _ = ingest(folder, name)
        np.testing.assert_array_equal(table[TIME].to_numpy(), t)
        np.testing.assert_allclose(table[list(ACC)].to_numpy(), ACC_G * G, rtol=1e-15)
        if name != "static":
            np.testing.assert_allclose(table[list(GYR)].to_numpy(), np.deg2rad(GYR_DPS), rtol=1e-15)
    short = {**arrays, "columns": {**arrays["columns"], "acc_z": ["SENSacc", 3]}}
    with pytest.raises(DeclarationError, match=r"recordings.poses.columns.acc_z: column index 3 "
                       r"not in 'SENSacc' of .*r.mat \(20 samples x 3 columns\)"):  # fmt: skip
        ingest(write_dataset(tmp_path, {"poses": short}), "poses")
    sio.savemat(tmp_path / "r.mat", {"MATLABtime": t[None, :-1], "SENSacc": ACC_G.T})
    with pytest.raises(DeclarationError, match=r"recordings.poses.columns.acc_x: 'SENSacc' in "
                       r".*r.mat has shape \(3, 20\), no dimension of 19 samples"):  # fmt: skip
        ingest(
            write_dataset(
                tmp_path,
                {
                    "poses": {
                        **arrays,
                        "units": {"acc": "g"},
                        "columns": {
                            k: v for k, v in arrays["columns"].items() if not k.startswith("gyr")
                        },
                    }
                },
            ),
            "poses",
        )
    table_entry = {"reader": "table", "file": "x.csv", "columns": {"acc_x": ["a", 0]}}
    (tmp_path / "x.csv").write_text("a\n1\n2\n")
    with pytest.raises(DeclarationError, match=r"columns.acc_x: source \['a', 0\] \(a column "
                       r"of a named array\) in the table"):  # fmt: skip
        ingest(write_dataset(tmp_path, {"poses": table_entry}), "poses")
