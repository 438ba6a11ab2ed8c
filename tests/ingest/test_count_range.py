"""Raw counts and the ADC's declared range (range_counts): at a limit a reading is clipped and
kept; beyond it, the ingest refuses the file naming the file, the line and the range."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from imucal import io
from imucal.columns import RAW_COLUMNS
from imucal.ingest import ingest_recording, ingest_to_parquet, sensor_limits
from imucal.ingest.summary import summarize_recording
from imucal.io.dataset import read_dataset

SENS = {"acc": 0.00239501953125, "gyr": 0.0002664624812205083, "mag": 0.001}
ROWS = 60


def session(folder: Path, range_counts: str = "") -> Path:
    folder.mkdir(exist_ok=True)
    sens = ", ".join(f"{k}: {v!r}" for k, v in SENS.items())
    (folder / "dataset.yaml").write_text(
        f"name: r\ngravity_m_s2: 9.81\nsensitivity: {{{sens}}}\n{range_counts}"
        "recordings: {rotation3d: rotation3d.csv}\n"
    )
    return folder / "rotation3d.csv"


def write_log(path: Path, gyr_x: dict[int, int] | None = None) -> None:
    """A valid log; ``gyr_x`` sets that column on some rows (row -> counts)."""
    lines = [",".join(RAW_COLUMNS)]
    for i in range(ROWS):
        g = (gyr_x or {}).get(i, -277)
        mag = "57,375,-614" if i % 10 == 0 else ",,"
        lines.append(f"{i / 100:.2f},{i},113,134,4064,{g},-60,10,{mag}")
    path.write_text("\n".join(lines) + "\n")


def refusal(path: Path, tmp_path: Path) -> str:
    """The message of the in-memory and the streamed ingest (the same); no parquet left."""
    dataset = read_dataset(path.parent)
    with pytest.raises(io.RawDataError) as whole:
        ingest_recording(path, "rotation3d", dataset, "test")
    out = tmp_path / "out" / "r.parquet"
    with pytest.raises(io.RawDataError) as streamed:
        ingest_to_parquet(path, "rotation3d", dataset, "test", out, batch_bytes=128)
    assert str(streamed.value) == str(whole.value)
    assert not out.parent.exists() or list(out.parent.iterdir()) == []
    return str(whole.value)


def test_readings_at_the_limits_are_clipped_samples_and_kept(tmp_path: Path) -> None:
    path = session(tmp_path, "range_counts: {gyr: 20000}\n")
    write_log(path, {5: 20000, 6: 20000, 40: -20000})
    dataset = read_dataset(tmp_path)
    table, metadata = ingest_recording(path, "rotation3d", dataset, "test")
    counts = np.rint(table["gyr_x"].to_numpy() / SENS["gyr"])
    assert counts[5] == counts[6] == 20000 and counts[40] == -20000
    # counted per sensor (in memory and streamed alike) and named in the summary
    assert metadata["clipped"] == {"acc": 0, "gyr": 3, "mag": 0}
    out = tmp_path / "out" / "r.parquet"
    ingest_to_parquet(path, "rotation3d", dataset, "test", out, batch_bytes=128)
    assert io.read_recording(out)[1]["clipped"] == metadata["clipped"]
    summary = summarize_recording(table, metadata)
    assert summary["clipped"] == metadata["clipped"]
    assert any("clipped" in note and "gyr 3" in note for note in summary["notes"])
    # the range in SI units that the fits leave clipped readings out by
    limit = sensor_limits([metadata], dataset.range_counts)["gyr"]
    assert np.count_nonzero(np.abs(table["gyr_x"].to_numpy()) >= limit) == 3


def test_a_count_beyond_the_range_is_refused_with_file_line_and_range(tmp_path: Path) -> None:
    path = session(tmp_path, "range_counts: {gyr: 20000}\n")
    write_log(path, {5: 20000, 41: -20001, 50: 25000})
    message = refusal(path, tmp_path)
    assert message == (
        f"{path}, line 43: gyr_x is -20001 counts, beyond the declared range -20000..20000 of "
        "the gyroscope (range_counts.gyr of dataset.yaml; 2 gyr count(s) beyond it in the "
        "file); expected counts within -20000..20000: a reading at a limit is a clipped sample "
        "and is kept, one beyond it cannot come from the ADC (the declared range is wrong or "
        "the logger overflowed)"
    )


def test_the_default_range_is_symmetric_int16(tmp_path: Path) -> None:
    path = session(tmp_path)
    write_log(path, {7: 32767, 8: -32767})
    ingest_recording(path, "rotation3d", read_dataset(tmp_path), "test")
    write_log(path, {7: -32768})
    assert refusal(path, tmp_path).startswith(
        f"{path}, line 9: gyr_x is -32768 counts, beyond the declared range -32767..32767"
    )


def test_a_twos_complement_range_is_declared_as_a_pair(tmp_path: Path) -> None:
    path = session(tmp_path, "range_counts: {gyr: [-32768, 32767]}\n")
    dataset = read_dataset(tmp_path)
    assert dataset.count_range["gyr"] == (-32768, 32767)
    assert dataset.range_counts["gyr"] == 32767  # |counts| >= 32767 is clipped downstream
    write_log(path, {7: -32768, 8: 32767})
    ingest_recording(path, "rotation3d", dataset, "test")
    write_log(path, {7: -32768, 30: 32768})
    assert refusal(path, tmp_path).startswith(
        f"{path}, line 32: gyr_x is 32768 counts, beyond the declared range -32768..32767"
    )


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("[5, 10]", "[5, 10]; expected [lowest, highest] with lowest < 0 < highest"),
        ("[-5]", "is not valid under any of the given schemas"),
        ("0", "is not valid under any of the given schemas"),
    ],
)
def test_a_bad_range_declaration_is_refused(tmp_path: Path, value: str, expected: str) -> None:
    session(tmp_path, f"range_counts: {{acc: {value}}}\n")
    with pytest.raises(ValueError, match="range_counts/acc") as info:
        read_dataset(tmp_path)
    assert expected in str(info.value)


def test_declared_counts_beyond_the_range_name_the_file_and_line(tmp_path: Path) -> None:
    # A table in counts with an offset (zero_counts) and flipped axes: the range applies to
    # counts - zero_counts in the file's own axes.
    lines = ["# logger v1", "t,ax,ay,az"]
    lines += [f"{i / 100:.2f},{32768 + 100},{32768 - 50},{32768 + 4000}" for i in range(30)]
    lines[2 + 12] = "0.12,65535,32718,36768"  # ax - 32768 = 32767: at the limit, kept
    (tmp_path / "acc.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "dataset.yaml").write_text(
        "name: d\ngravity_m_s2: 9.81\nrange_counts: {acc: [-32768, 32767]}\n"
        "recordings:\n  static:\n    reader: table\n    file: acc.csv\n    skip_lines: 1\n"
        "    columns: {t_s: t, acc_x: ax, acc_y: ay, acc_z: az}\n    units: {acc: counts}\n"
        "    sensitivity: {acc: 0.0024}\n    zero_counts: {acc: 32768}\n"
        "    axes: {acc: [-x, y, z]}\n"
    )
    dataset = read_dataset(tmp_path)
    table, _ = ingest_recording(dataset.recordings["static"], "static", dataset, "test")
    assert table["acc_x"].iloc[12] == pytest.approx(-32767 * 0.0024)
    lines[2 + 20] = "0.20,32868,32718,65537"  # az - 32768 = 32769
    (tmp_path / "acc.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(io.RawDataError) as info:
        ingest_recording(dataset.recordings["static"], "static", dataset, "test")
    assert str(info.value).startswith(
        f"{tmp_path / 'acc.csv'}, line 23: acc_z is 32769 counts, beyond the declared range "
        "-32768..32767 of the accelerometer"
    )
