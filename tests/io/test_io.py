"""Reading raw logs and the reference, parquet with metadata, calibration files (imucal.io)."""

from __future__ import annotations

import csv
import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from imucal import io
from imucal.calibration import FORMAT_VERSION, ImuCalibration, SensorCalibration
from imucal.columns import ACC, GYR, MAG, RAW_COLUMNS, SEQ, SEQ_MODULUS, TIME
from imucal.constants import IMU_RECORDINGS
from imucal.ingest import (
    check_log,
    counts_to_si,
    ingest_recording,
    reference_to_table,
    summarize_dataset,
    summarize_recording,
)
from imucal.ingest.timebase import resolve_packet_steps
from imucal.io import store
from imucal.io.dataset import read_dataset

SENSITIVITY = {"acc": 0.00239501953125, "gyr": 0.0002664624812205083, "mag": 0.001}


@pytest.fixture
def clean(conformance_dir: Path) -> Path:
    """../shared/data/conformance/clean (skips with the reason when ../shared is absent)."""
    return conformance_dir


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def write_log(path: Path, seq: list[int], t_s: list[float], extra: str | None = None) -> None:
    """A small raw log: counts from the row index, mag on every 10th row."""
    header = ",".join(RAW_COLUMNS) + (f",{extra}" if extra else "")
    lines = [header]
    for i, (s, t) in enumerate(zip(seq, t_s)):
        mag = f"{100 + i},{-200 - i},{300 + i}" if i % 10 == 0 else ",,"
        row = f"{t:.4f},{s},{i},{-i},{4000 + i},{7 * i},{-3},{5},{mag}"
        lines.append(row + (f",{20 + i / 100:.2f}" if extra else ""))
    path.write_text("\n".join(lines) + "\n")


# --------------------------------------------------------------------------------------------
# The conformance session, read unchanged


def read_with_csv_module(path: Path) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Independent reading: counts as float (NaN where empty) and the mask of empty mag cells."""
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    cols = {c: np.array([float(r[c]) if r[c] != "" else np.nan for r in rows]) for c in RAW_COLUMNS}
    empty = np.array([[r[c] == "" for c in MAG] for r in rows])
    return cols, empty


@pytest.mark.parametrize("recording", IMU_RECORDINGS)
def test_conformance_values_are_counts_times_sensitivity(clean: Path, recording: str) -> None:
    dataset = read_dataset(clean)
    path = dataset.recordings[recording]
    before = sha256(path)
    table, metadata = ingest_recording(path, recording, dataset, imucal_version="test")
    expected, empty = read_with_csv_module(path)
    assert list(table.columns) == list(RAW_COLUMNS)
    assert len(table) == len(expected[TIME])
    np.testing.assert_array_equal(table[TIME].to_numpy(), expected[TIME])
    np.testing.assert_array_equal(table[SEQ].to_numpy(), expected[SEQ].astype(np.int64))
    for sensor, columns in (("acc", ACC), ("gyr", GYR), ("mag", MAG)):
        for c in columns:
            # Exact: the same float64 product, NaN in the same places.
            np.testing.assert_array_equal(
                table[c].to_numpy(), expected[c] * dataset.sensitivity[sensor]
            )
    # Mag NaN exactly where the file has empty cells (10 Hz of 100 Hz), never filled.
    np.testing.assert_array_equal(np.isnan(table[list(MAG)].to_numpy()), empty)
    assert 0 < (~empty[:, 0]).sum() < len(table) / 5
    assert metadata["sha256"] == before == sha256(path)  # the shared file is untouched
    assert metadata["sensitivity"] == dataset.sensitivity
    assert metadata["units"]["acc_x"] == "m/s^2" and metadata["units"]["gyr_z"] == "rad/s"


def test_conformance_reference_units_and_times(clean: Path) -> None:
    dataset = read_dataset(clean)
    path = dataset.recordings["reference"]
    table, metadata = ingest_recording(path, "reference", dataset, imucal_version="test")
    text = [line for line in path.read_text().splitlines() if not line.startswith("//")]
    names = text[0].split("\t")
    raw = np.array([[float(x) for x in line.split("\t")] for line in text[1:]])
    col = {n: raw[:, k] for k, n in enumerate(names)}
    assert metadata["first_line"] == 8 and metadata["update_rate_hz"] == 100.0
    assert metadata["sensitivity"] is None
    np.testing.assert_array_equal(table[SEQ].to_numpy(), col["PacketCounter"].astype(np.int64))
    np.testing.assert_array_equal(table[TIME].to_numpy(), col["SampleTimeFine"] / 10_000)
    for ours, theirs in zip((*ACC, *GYR, *MAG), names[2:11]):
        np.testing.assert_array_equal(table[ours].to_numpy(), col[theirs])
    assert table[TIME].iloc[0] == 100.0
    np.testing.assert_allclose(np.diff(table[TIME].to_numpy()), 0.01, rtol=1e-9)
    # Units: at rest (first 5 s) |acc| is g in m/s^2 and |mag| is 1. Tolerance: 5 standard
    # errors of the mean from the sample scatter (a unit error would be off by a factor >= 9.8).
    rest = table[TIME].to_numpy() < 105.0
    for columns, value in ((ACC, dataset.gravity_m_s2), (MAG, 1.0)):
        norm = np.linalg.norm(table.loc[rest, list(columns)].to_numpy(), axis=1)
        tol = 5 * norm.std(ddof=1) / np.sqrt(norm.size)
        assert abs(norm.mean() - value) < tol, (columns, norm.mean(), tol)


def test_conformance_summary(clean: Path, tmp_path: Path) -> None:
    dataset = read_dataset(clean)
    recordings = {}
    for name, path in dataset.recordings.items():
        table, metadata = ingest_recording(path, name, dataset, imucal_version="test")
        io.write_recording(table, tmp_path / f"{name}.parquet", metadata)
        recordings[name] = io.read_recording(tmp_path / f"{name}.parquet")
    summary = summarize_dataset(recordings, dataset="clean")
    io.write_json(summary, tmp_path / "summary.json")
    back = json.loads((tmp_path / "summary.json").read_text())
    assert back == summary
    assert back["lost_packets"] == 0
    rot = back["recordings"]["rotation3d"]
    assert rot["rows"] == 7936 and rot["duration_s"] == pytest.approx(79.35, abs=1e-9)
    assert rot["rate_hz"] == pytest.approx(100.0, rel=1e-12)
    assert rot["mag_samples"] == 794 and rot["mag_rate_hz"] == pytest.approx(10.0, rel=1e-12)
    assert back["recordings"]["reference"]["mag_samples"] == 7936


# --------------------------------------------------------------------------------------------
# Native CSV: extra columns, metadata round trip, atomic write


def test_extra_columns_are_kept(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    write_log(path, list(range(25)), [i / 100 for i in range(25)], extra="temp_c")
    counts = io.read_imu_csv(path)
    assert list(counts.columns) == [*RAW_COLUMNS, "temp_c"]
    assert counts["acc_z"].dtype == np.int64 and counts["mag_x"].dtype == np.float64
    table = counts_to_si(counts, SENSITIVITY)
    np.testing.assert_array_equal(table["temp_c"], 20 + np.arange(25) / 100)
    np.testing.assert_array_equal(table["acc_z"], (4000 + np.arange(25)) * SENSITIVITY["acc"])
    np.testing.assert_array_equal(table["mag_y"].notna(), np.arange(25) % 10 == 0)


def test_recording_round_trip_with_metadata(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    write_log(path, list(range(30)), [i / 100 for i in range(30)], extra="temp_c")
    table = counts_to_si(io.read_imu_csv(path), SENSITIVITY)
    metadata = {
        "dataset": "t",
        "recording": "cube",
        "source": str(path),
        "sha256": io.sha256_file(path),
        "sensitivity": SENSITIVITY,
        "units": {"acc_x": "m/s^2"},
    }
    target = tmp_path / "out" / "cube.parquet"
    io.write_recording(table, target, metadata)
    back, meta = io.read_recording(target)
    pd.testing.assert_frame_equal(back, table)
    assert meta == metadata
    # Counts are recoverable from the SI values: value / sensitivity is within a few ulp of the
    # integer count, so rounding gives it back exactly.
    recovered = back["gyr_x"].to_numpy() / SENSITIVITY["gyr"]
    np.testing.assert_allclose(recovered, 7.0 * np.arange(30), rtol=4 * np.finfo(float).eps)
    np.testing.assert_array_equal(np.rint(recovered), 7.0 * np.arange(30))
    assert sorted(p.name for p in target.parent.iterdir()) == ["cube.parquet"]


def test_failed_write_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def write_half_then_fail(table: object, where: str, **options: object) -> None:
        Path(where).write_bytes(b"PAR1 partial")
        raise OSError("disk full")

    monkeypatch.setattr(store.pq, "write_table", write_half_then_fail)
    table = pd.DataFrame({TIME: [0.0, 0.01], SEQ: [0, 1]})
    with pytest.raises(OSError, match="disk full"):
        io.write_recording(table, tmp_path / "x.parquet", {"dataset": "t"})
    assert list(tmp_path.iterdir()) == []


def test_read_recording_refuses_foreign_parquet(tmp_path: Path) -> None:
    pd.DataFrame({"a": [1.0]}).to_parquet(tmp_path / "other.parquet")
    with pytest.raises(ValueError, match=r"other\.parquet: no 'imucal' parquet metadata"):
        io.read_recording(tmp_path / "other.parquet")


# --------------------------------------------------------------------------------------------
# Packet counter: lost packets across wraps


def test_lost_packets_across_the_wrap(tmp_path: Path) -> None:
    # 65533 .. 1: no loss over the wrap; 1 -> 4 loses 2 (2, 3); 5 -> 65530 after 655.25 s
    # loses 65524; 65531 -> 65535 loses 3; 65535 -> 3 loses 3 across the wrap (0, 1, 2).
    seq = [65533, 65534, 65535, 0, 1, 4, 5, 65530, 65531, 65535, 3, 4]
    t_s = [0.00, 0.01, 0.02, 0.03, 0.04, 0.07, 0.08, 655.33, 655.34, 655.38, 655.42, 655.43]
    path = tmp_path / "log.csv"
    write_log(path, seq, t_s)
    counts = io.read_imu_csv(path)
    table = counts_to_si(counts, SENSITIVITY)
    check_log(table, path, first_line=2)
    advance, rate = resolve_packet_steps(table[SEQ].to_numpy(), table[TIME].to_numpy())
    assert rate == pytest.approx(100.0, rel=1e-9)
    # 5 -> 65530 in 655.25 s: 65525 packets by seq alone, the time says the same (no extra wrap).
    np.testing.assert_array_equal(advance, [1, 1, 1, 1, 3, 1, 65525, 1, 4, 4, 1])
    summary = summarize_recording(table, {"first_line": 2})
    assert summary["lost_packets"] == 2 + 65524 + 3 + 3
    assert summary["n_gaps"] == 4
    assert [g["line"] for g in summary["gaps"]] == [7, 9, 11, 12]
    assert summary["gaps"][0] == {
        "line": 7,
        "t_s": 0.07,
        "dt_s": pytest.approx(0.03),
        "seq_before": 1,
        "seq": 4,
        "lost": 2,
    }
    assert summary["duplicated_rows"] == summary["out_of_order_rows"] == 0


def test_silence_longer_than_a_wrap_is_counted_from_time() -> None:
    # 100 Hz; after row 199 the radio is silent for 1000.00 s = 100000 packets: seq advances by
    # 100000 mod 65536 = 34464, which alone would read as 31072 packets *back*.
    t_s = np.r_[np.arange(200) * 0.01, 1000.0 + 1.99 + np.arange(200) * 0.01]
    seq = np.r_[np.arange(200), 199 + 100_000 + np.arange(200)] % SEQ_MODULUS
    advance, rate = resolve_packet_steps(seq, t_s)
    assert rate == pytest.approx(100.0, rel=1e-9)
    assert advance[199] == 100_000
    assert np.all(np.delete(advance, 199) == 1)


def test_summary_counts_duplicates_and_out_of_order() -> None:
    seq = [10, 11, 11, 12, 14, 13, 15]
    table = pd.DataFrame({TIME: np.arange(7) * 0.01, SEQ: seq, MAG[0]: [1.0] + [np.nan] * 6})
    summary = summarize_recording(table, {"first_line": 5})
    assert summary["duplicated_rows"] == 1
    assert summary["out_of_order_rows"] == 1
    assert summary["lost_packets"] == 1 + 1  # 12 -> 14 and 13 -> 15 (13 counted late)
    assert summary["mag_samples"] == 1 and summary["mag_rate_hz"] is None


# --------------------------------------------------------------------------------------------
# MT Manager export variants


MT_HEADER = "// Start Time: 2013-11-04 10:21:33.000\n// Update Rate: 50.0Hz\n"


def test_reference_without_sample_time_uses_counter_and_rate(tmp_path: Path) -> None:
    # PacketCounter wraps; trailing tab as MT Manager writes it; an extra column is kept.
    counter = [65534, 65535, 0, 1]
    lines = ["PacketCounter\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\tMag_X\tMag_Y\tMag_Z\tTemp\t"]
    for c in counter:
        lines.append(f"{c}\t0.1\t0.2\t9.8\t0.01\t0.02\t0.03\t0.5\t0.1\t-0.8\t24.5\t")
    path = tmp_path / "mtx.txt"
    path.write_text(MT_HEADER + "\n".join(lines) + "\n")
    export = io.read_mt_manager_export(path)
    assert export.update_rate_hz == 50.0 and export.first_line == 4
    table = reference_to_table(export)
    np.testing.assert_allclose(table[TIME], np.array([65534, 65535, 65536, 65537]) / 50.0)
    assert list(table.columns) == [*RAW_COLUMNS, "Temp"]
    np.testing.assert_array_equal(table["acc_z"], 9.8)


def test_reference_sample_time_fine_wraps_at_32_bits(tmp_path: Path) -> None:
    ticks = [2**32 - 200, 2**32 - 100, 0, 100]
    lines = [
        "PacketCounter\tSampleTimeFine\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\tMag_X\tMag_Y\tMag_Z"
    ]
    for k, tick in enumerate(ticks):
        lines.append(f"{k}\t{tick}\t0\t0\t9.8\t0\t0\t0\t1\t0\t0")
    path = tmp_path / "mtx.txt"
    path.write_text(MT_HEADER + "\n".join(lines) + "\n")
    table = reference_to_table(io.read_mt_manager_export(path))
    # t_s ~ 429497 s: float64 resolves it to np.spacing(t_s) ~ 6e-11 s, the only tolerance.
    atol = 2 * np.spacing(table[TIME].max())
    np.testing.assert_allclose(np.diff(table[TIME]), 0.01, rtol=0, atol=atol)


# --------------------------------------------------------------------------------------------
# Calibration files


def calibration() -> ImuCalibration:
    rng = np.random.default_rng(3)
    sensors = []
    for sensor, unit in (("acc", "m/s^2"), ("gyr", "rad/s"), ("mag", "normalised")):
        matrix = np.eye(3) + 0.01 * rng.standard_normal((3, 3))
        std = {"bias": np.full(3, 1e-3)}
        sensors.append(SensorCalibration(sensor, rng.standard_normal(3), matrix, unit, std, "t"))
    return ImuCalibration(*sensors)


def test_calibration_round_trip(tmp_path: Path) -> None:
    cal = calibration()
    io.write_calibration(cal, tmp_path / "calibration.json")
    back = io.read_calibration(tmp_path / "calibration.json")
    for sensor in ("acc", "gyr", "mag"):
        a, b = cal.sensor(sensor), back.sensor(sensor)
        # JSON keeps float64 exactly (repr round trip).
        np.testing.assert_array_equal(a.matrix, b.matrix)
        np.testing.assert_array_equal(a.bias, b.bias)
        np.testing.assert_array_equal(a.std["bias"], b.std["bias"])
        assert (a.unit, a.method) == (b.unit, b.method)


def test_calibration_refuses_newer_format(tmp_path: Path) -> None:
    d = calibration().to_dict()
    d["format_version"] = FORMAT_VERSION + 1
    (tmp_path / "cal.json").write_text(json.dumps(d))
    with pytest.raises(
        ValueError, match=rf"cal\.json: .*format_version {FORMAT_VERSION + 1} is newer"
    ):
        io.read_calibration(tmp_path / "cal.json")


def test_calibration_refuses_wrong_unit(tmp_path: Path) -> None:
    d = calibration().to_dict()
    d["gyr"]["unit_in"] = "deg/s"
    (tmp_path / "cal.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match=r"cal\.json: .*'gyr' is for unit 'deg/s'.*'rad/s'"):
        io.read_calibration(tmp_path / "cal.json")


def test_calibration_file_not_json(tmp_path: Path) -> None:
    (tmp_path / "cal.json").write_text('{\n  "format_version": 1,\n  oops\n}\n')
    with pytest.raises(ValueError, match=r"cal\.json, line 3: not valid JSON"):
        io.read_calibration(tmp_path / "cal.json")


# --------------------------------------------------------------------------------------------
# Segments and result tables


def segments() -> pd.DataFrame:
    return pd.DataFrame(
        {
            "recording": ["rotation3d", "cube"],
            "label": ["x", "p01"],
            "kind": ["phase", "position"],
            "start_s": [1.5, 10.0],
            "end_s": [20.25, 15.0],
            "start_index": [150, 1000],
            "end_index": [2025, 1500],
            "axis": ["x", ""],
            "rate_dps": [np.nan, np.nan],
            "sense": [1, 0],
            "turns": [2.0, np.nan],
            "up": ["", "+z"],
            "angle_deg": [360.0, np.nan],
        }
    )


def test_segments_round_trip(tmp_path: Path) -> None:
    io.write_recording(segments(), tmp_path / "segments.parquet", {"dataset": "t"})
    pd.testing.assert_frame_equal(io.read_segments(tmp_path / "segments.parquet"), segments())


def test_segments_refuses_missing_column(tmp_path: Path) -> None:
    io.write_recording(segments().drop(columns="turns"), tmp_path / "s.parquet", {})
    with pytest.raises(
        ValueError, match=r"s\.parquet: segments table lacks the columns \['turns'\]"
    ):
        io.read_segments(tmp_path / "s.parquet")


def test_write_table_round_trip(tmp_path: Path) -> None:
    table = pd.DataFrame(
        {
            "table": ["I", "II"],
            "row": ["LS", "w/o tools"],
            "x": [0.1 / 3, 1.1526],
            "y": [-2e-7, 1.0],
        }
    )
    io.write_table(table, tmp_path / "out" / "tables.csv")
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "out" / "tables.csv"), table)


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ("\ngravity_m_s2:", "\ngravity_ms2:", "key 'gravity_ms2' is not a known key here, did you mean 'gravity_m_s2'?"),
        ("gyr: ", "gry: ", "key 'sensitivity/gry' is not a known key here, did you mean 'gyr'?"),
    ],
)  # fmt: skip
def test_a_misspelt_key_of_dataset_yaml_names_the_closest_setting(tmp_path, old, new, expected):
    text = (Path(__file__).resolve().parents[2] / "data/demo/dataset.yaml").read_text()
    assert old in text
    (tmp_path / "dataset.yaml").write_text(text.replace(old, new, 1))
    with pytest.raises(ValueError) as info:
        read_dataset(tmp_path)
    message = str(info.value)
    assert message.startswith(f"{tmp_path / 'dataset.yaml'}: {expected} Known keys here: ")
    assert "does not match any of the regexes" not in message


def test_artifacts_get_the_permissions_of_a_new_file(tmp_path):
    """Written atomically through a temporary file, an artifact still gets what ``open`` would
    give it (0o666 less the umask), not the temporary file's owner-only mode."""
    import os
    import stat

    umask = os.umask(0o022)
    try:
        io.write_json({"a": 1}, tmp_path / "a.json")
        io.write_recording(pd.DataFrame({TIME: [0.0, 0.01]}), tmp_path / "r.parquet", {})
    finally:
        os.umask(umask)
    for name in ("a.json", "r.parquet"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o644, name
