"""Streamed ingest: batches of a native CSV give the file the whole table gives, and the checks
carried over batch boundaries (counter wrap, time order, gaps, lines in errors) are exact."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from imucal import io
from imucal.columns import MAG, RAW_COLUMNS, SEQ, SEQ_MODULUS, TIME
from imucal.ingest import LogChecks, check_log, ingest_recording, ingest_to_parquet
from imucal.io.dataset import read_dataset

SENSITIVITY = "{acc: 0.00239501953125, gyr: 0.0002664624812205083, mag: 0.001}"
#: Bytes per batch: a handful of the fixed-width lines below, so a log has many boundaries.
BATCH = 400


def session(folder: Path) -> Path:
    folder.mkdir(exist_ok=True)
    (folder / "dataset.yaml").write_text(
        f"name: s\ngravity_m_s2: 9.81\nsensitivity: {SENSITIVITY}\n"
        "recordings: {rotation3d: rotation3d.csv}\n"
    )
    return folder / "rotation3d.csv"


def write_log(path: Path, seq: np.ndarray, t_s: np.ndarray) -> None:
    """Fixed-width lines (every cell zero-padded): an edit of a value keeps every line's byte
    offset, so the batch boundaries stay where they were found."""
    lines = [",".join((*RAW_COLUMNS, "temp_c"))]
    for i, (s, t) in enumerate(zip(seq, t_s)):
        mag = f"{100 + i % 50:04d},{200:04d},{300:04d}" if i % 10 == 0 else "    ,    ,    "
        mag = mag.replace(" ", "")  # empty cells: the only variable width, fixed per row kind
        lines.append(
            f"{t:010.4f},{s:05d},{i % 1000:04d},0134,4064,0277,0060,0010,{mag},{20 + i % 7:05.2f}"
        )
    path.write_text("\n".join(lines) + "\n")


def batch_starts(path: Path, batch_bytes: int = BATCH) -> list[int]:
    """First row of every batch after the first, as the stream cuts the file."""
    starts, row = [], 0
    for batch in io.ImuCsvStream(path, batch_bytes):
        row += batch.num_rows
        starts.append(row)
    return starts[:-1]


def regular(n: int, first_seq: int = 0) -> tuple[np.ndarray, np.ndarray]:
    return (first_seq + np.arange(n)) % SEQ_MODULUS, np.arange(n) / 100


def ingest_both(path: Path, tmp: Path, batch_bytes: int = BATCH):
    dataset = read_dataset(path.parent)
    table, metadata = ingest_recording(path, "rotation3d", dataset, "test")
    io.write_recording(table, tmp / "whole.parquet", metadata)
    streamed = ingest_to_parquet(
        path, "rotation3d", dataset, "test", tmp / "streamed.parquet", batch_bytes=batch_bytes
    )
    return table, metadata, streamed


def test_boundaries_are_where_the_tests_put_their_cases(tmp_path: Path) -> None:
    path = session(tmp_path)
    write_log(path, *regular(120))
    starts = batch_starts(path)
    assert len(starts) >= 10  # many boundaries
    seq, t_s = regular(120)
    t_s[starts[2]] = 0.5  # same width: the boundaries do not move
    write_log(path, seq, t_s)
    assert batch_starts(path) == starts


# 16 bytes: shorter than a line, so lines are carried over several reads
@pytest.mark.parametrize("batch_bytes", [16, 128, BATCH, 1 << 20])
def test_streamed_file_equals_the_whole_table(tmp_path: Path, batch_bytes: int) -> None:
    path = session(tmp_path)
    seq, t_s = regular(300, first_seq=65500)  # wraps at row 36
    seq[200:] = (seq[200:] + 7) % SEQ_MODULUS  # 7 packets lost before row 200
    t_s[200:] += 0.07
    write_log(path, seq, t_s)
    table, metadata, streamed = ingest_both(path, tmp_path, batch_bytes)
    assert streamed == metadata
    assert metadata["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    whole = pq.read_table(tmp_path / "whole.parquet")
    parts = pq.read_table(tmp_path / "streamed.parquet")
    # Same values, nulls (no magnetometer sample), types, names and schema metadata.
    assert parts.equals(whole)
    assert parts.schema.equals(whole.schema, check_metadata=True)
    assert parts.column(MAG[0]).null_count == 270
    back, meta = io.read_recording(tmp_path / "streamed.parquet")
    assert meta == metadata and back.equals(table)
    if batch_bytes < 1 << 20:
        assert pq.read_metadata(tmp_path / "streamed.parquet").num_row_groups > 1


def test_seq_wrap_on_a_batch_boundary_loses_nothing(tmp_path: Path) -> None:
    path = session(tmp_path)
    write_log(path, *regular(120))
    b = batch_starts(path)[3]
    seq, t_s = regular(120, first_seq=SEQ_MODULUS - b)  # row b - 1: 65535, row b: 0
    write_log(path, seq, t_s)
    assert batch_starts(path)[3] == b and (seq[b - 1], seq[b]) == (65535, 0)
    table, _, _ = ingest_both(path, tmp_path)
    assert pq.read_table(tmp_path / "streamed.parquet").equals(
        pq.read_table(tmp_path / "whole.parquet")
    )
    np.testing.assert_array_equal(table[SEQ].to_numpy(), seq)


def test_silence_longer_than_a_wrap_on_a_batch_boundary(tmp_path: Path) -> None:
    # 700 s of silence at 100 Hz = 70000 packets: seq advances by 70000 mod 65536 = 4464, and
    # only the packet rate of the whole log (from the other batches) says how many wraps.
    path = session(tmp_path)
    write_log(path, *regular(120))
    b = batch_starts(path)[4]
    seq, t_s = regular(120)
    seq[b:] = (seq[b:] + 70000 - 1) % SEQ_MODULUS
    t_s[b:] += 700.0 - 0.01
    write_log(path, seq, t_s)
    assert batch_starts(path)[4] == b
    ingest_both(path, tmp_path)  # no error: the step advanced
    check_log(
        io.read_recording(tmp_path / "streamed.parquet")[0], path, first_line=2
    )  # and the whole table agrees


def fails_alike(path: Path, tmp_path: Path) -> str:
    """The in-memory and the streamed ingest raise the same message; no parquet is left."""
    dataset = read_dataset(path.parent)
    with pytest.raises(io.RawDataError) as whole:
        ingest_recording(path, "rotation3d", dataset, "test")
    out = tmp_path / "out" / "r.parquet"
    with pytest.raises(io.RawDataError) as streamed:
        ingest_to_parquet(path, "rotation3d", dataset, "test", out, batch_bytes=BATCH)
    assert not out.parent.exists() or list(out.parent.iterdir()) == []
    assert str(streamed.value) == str(whole.value)
    return str(whole.value)


def test_time_reversal_on_a_batch_boundary(tmp_path: Path) -> None:
    path = session(tmp_path)
    write_log(path, *regular(120))
    b = batch_starts(path)[2]
    seq, t_s = regular(120)
    t_s[b] = t_s[b - 2]  # row b is earlier than row b - 1, the last row of the batch before
    write_log(path, seq, t_s)
    assert batch_starts(path)[2] == b
    message = fails_alike(path, tmp_path)
    assert message == (
        f"{path}, line {b + 2}: t_s {float(t_s[b])!r} s is earlier than {float(t_s[b - 1])!r} s on line "
        f"{b + 1}; expected non-decreasing receiver time t_s"
    )


@pytest.mark.parametrize(("step", "what"), [(0, "repeats"), (-1, "goes back")])
def test_duplicated_or_backward_seq_on_a_batch_boundary(
    tmp_path: Path, step: int, what: str
) -> None:
    path = session(tmp_path)
    write_log(path, *regular(120))
    b = batch_starts(path)[5]
    seq, t_s = regular(120)
    seq[b:] = seq[b:] - 1 + step  # row b: the seq of row b - 1 (0) or one before it (-1)
    write_log(path, seq, t_s)
    assert batch_starts(path)[5] == b
    message = fails_alike(path, tmp_path)
    if step == 0:
        found = f"seq {seq[b]} repeats the seq of line {b + 1} (duplicated packet)"
    else:
        found = f"seq {seq[b]} goes back from {seq[b - 1]} on line {b + 1} (out-of-order packet)"
    assert message == (
        f"{path}, line {b + 2}: {found}; expected each packet once, in order "
        "(seq increasing modulo 65536)"
    )
    assert what in message


def test_the_first_problem_of_the_file_wins_whatever_the_batches(tmp_path: Path) -> None:
    # A time reversal late in the file and a partial magnetometer row later still: the format
    # problem is reported (as for the whole table), though the reversal comes first.
    path = session(tmp_path)
    seq, t_s = regular(120)
    t_s[30] = t_s[28]
    write_log(path, seq, t_s)
    lines = path.read_text().splitlines()
    cells = lines[100 + 1].split(",")
    cells[8] = ""  # row 100 has a magnetometer sample: drop one of its three cells
    lines[100 + 1] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    message = fails_alike(path, tmp_path)
    assert message.startswith(f"{path}, line 102: mag_x empty but not the other")


def test_log_checks_split_anywhere_give_the_message_of_the_whole() -> None:
    seq, t_s = regular(40, first_seq=65530)
    cases = {"back": (seq.copy(), t_s.copy()), "dup": (seq.copy(), t_s.copy())}
    cases["back"][1][17] = 0.05
    cases["dup"][0][23:] -= 1
    cases["nan"] = (seq.copy(), t_s.copy())
    cases["nan"][1][9] = np.nan
    for name, (s, t) in cases.items():
        whole = LogChecks("f.csv", first_line=2)
        whole.update(t, s)
        with pytest.raises(io.RawDataError) as expected:
            whole.finish()
        for k in range(1, 40):
            for j in (k + 1, k + 3):
                checks = LogChecks("f.csv", first_line=2)
                for a, b in ((0, k), (k, j), (j, 40)):
                    checks.update(t[a:b], s[a:b])
                with pytest.raises(io.RawDataError) as got:
                    checks.finish()
                assert str(got.value) == str(expected.value), (name, k, j)


def test_writer_leaves_nothing_when_the_ingest_fails(tmp_path: Path) -> None:
    target = tmp_path / "out" / "x.parquet"
    with pytest.raises(RuntimeError, match="stop"), io.RecordingWriter(target, {TIME: float}) as w:
        w.write({TIME: np.arange(3.0)})
        raise RuntimeError("stop")
    assert list(target.parent.iterdir()) == []
