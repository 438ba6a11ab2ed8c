"""Bad input: one clear error naming the file, the line and the expectation; no parquet left.

Each case breaks one thing in an otherwise valid small session and runs the ingest in memory
(read_dataset -> ingest_recording -> write_recording) and as the rule script does
(ingest_to_parquet), streamed in batches of :data:`TINY_BATCH` bytes (two rows, so a batch
boundary falls next to every line): both must raise the same message.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from imucal.columns import RAW_COLUMNS
from imucal.ingest import ingest_recording, ingest_to_parquet
from imucal.io import RawDataError, write_recording
from imucal.io.dataset import read_dataset

REPO = Path(__file__).resolve().parents[2]
HEADER = ",".join(RAW_COLUMNS)
ROWS = 40
#: Bytes per batch of the streamed ingest in these tests: two lines of the log.
TINY_BATCH = 128

DATASET_YAML = """\
name: broken
gravity_m_s2: 9.81
sensitivity: {acc: 0.00239501953125, gyr: 0.0002664624812205083, mag: 0.001}
recordings:
  rotation3d: rotation3d.csv
  cube: cube.csv
  reference: mtx.txt
"""

MTX = """\
// Start Time: 2013-11-04 10:21:33.000
// Update Rate: 100.0Hz
PacketCounter\tSampleTimeFine\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\tMag_X\tMag_Y\tMag_Z
"""


def log_lines() -> list[str]:
    """A valid raw log as text lines: header on line 1, row i on line i + 2."""
    lines = [HEADER]
    for i in range(ROWS):
        mag = f"{57 + i},{375 - i},-614" if i % 10 == 0 else ",,"
        lines.append(f"{i / 100:.4f},{i},{113 + i},134,4064,-277,-60,10,{mag}")
    return lines


def mtx_text() -> str:
    rows = [
        f"{i}\t{1_000_000 + 100 * i}\t0.07\t-0.21\t9.80\t-0.0007\t0.0004\t-0.0005"
        "\t0.15\t0.43\t-0.89"
        for i in range(ROWS)
    ]
    return MTX + "\n".join(rows) + "\n"


@pytest.fixture
def session(tmp_path: Path) -> Path:
    folder = tmp_path / "session"
    folder.mkdir()
    (folder / "dataset.yaml").write_text(DATASET_YAML)
    for name in ("rotation3d.csv", "cube.csv"):
        (folder / name).write_text("\n".join(log_lines()) + "\n")
    (folder / "mtx.txt").write_text(mtx_text())
    return folder


def ingest_fails(folder: Path, recording: str = "rotation3d") -> str:
    """Ingest in memory and streamed; return the error message (the same for both); check that
    no parquet was left."""
    out = folder.parent / "results" / f"{recording}.parquet"
    messages = []
    for streamed in (False, True):
        with pytest.raises((RawDataError, FileNotFoundError, ValueError)) as info:
            dataset = read_dataset(folder)
            raw = dataset.recordings[recording]
            if streamed:
                ingest_to_parquet(raw, recording, dataset, "test", out, batch_bytes=TINY_BATCH)
            else:
                table, metadata = ingest_recording(raw, recording, dataset, imucal_version="test")
                write_recording(table, out, metadata)
        assert not out.parent.exists() or list(out.parent.iterdir()) == []
        messages.append(str(info.value))
    assert messages[0] == messages[1]
    assert "\n" not in messages[0]  # one message, one line
    return messages[0]


def write(folder: Path, lines: list[str], name: str = "rotation3d.csv", end: str = "\n") -> Path:
    path = folder / name
    path.write_text("\n".join(lines) + end)
    return path


def test_valid_session_ingests(session: Path, tmp_path: Path) -> None:
    # The fixture itself is valid, so each failure below is due to the one change it makes.
    dataset = read_dataset(session)
    for name in ("rotation3d", "cube", "reference"):
        table, _ = ingest_recording(dataset.recordings[name], name, dataset, "test")
        assert len(table) == ROWS


def test_missing_file(session: Path) -> None:
    (session / "rotation3d.csv").unlink()
    message = ingest_fails(session)
    assert re.search(r"rotation3d\.csv: raw IMU recording \(CSV\) not found; expected", message)


def test_dataset_yaml_missing_key(session: Path) -> None:
    text = DATASET_YAML.replace("gravity_m_s2: 9.81\n", "")
    (session / "dataset.yaml").write_text(text)
    message = ingest_fails(session)
    assert "dataset.yaml: key '(top level)': 'gravity_m_s2' is a required property" in message


def test_dataset_yaml_wrong_type(session: Path) -> None:
    text = DATASET_YAML.replace("acc: 0.00239501953125", "acc: fast")
    (session / "dataset.yaml").write_text(text)
    message = ingest_fails(session)
    assert "dataset.yaml: key 'sensitivity/acc': 'fast' is not of type 'number'" in message


def test_unknown_recording_name(session: Path) -> None:
    text = DATASET_YAML.replace("  cube: cube.csv\n", "  cube: cube.csv\n  rotation3D: r.csv\n")
    (session / "dataset.yaml").write_text(text)
    message = ingest_fails(session)
    assert (
        "dataset.yaml: key 'recordings/rotation3D' is not a known key here, did you mean "
        "'rotation3d'?" in message
    )


def test_missing_column(session: Path) -> None:
    lines = log_lines()
    lines[0] = HEADER.replace("gyr_y,", "")
    lines[1:] = [",".join(c for k, c in enumerate(line.split(",")) if k != 6) for line in lines[1:]]
    write(session, lines)
    message = ingest_fails(session)
    assert "rotation3d.csv, line 1: missing column 'gyr_y'; expected the header t_s,seq," in message


def test_misspelled_column(session: Path) -> None:
    lines = log_lines()
    lines[0] = HEADER.replace("acc_z", "acc_Z")
    write(session, lines)
    message = ingest_fails(session)
    assert "rotation3d.csv, line 1: missing column 'acc_z' (found 'acc_Z' instead?)" in message
    assert "expected the header t_s,seq,acc_x,acc_y,acc_z," in message


def test_non_numeric_cell(session: Path) -> None:
    lines = log_lines()
    lines[17] = lines[17].replace(",-277,", ",-2x7,")
    write(session, lines)
    message = ingest_fails(session)
    assert message.endswith(
        "rotation3d.csv, line 18: column 'gyr_x' holds '-2x7'; expected an integer raw count"
    )


def test_non_numeric_cell_in_reference(session: Path) -> None:
    text = mtx_text().splitlines()
    text[3 + 5] = text[3 + 5].replace("9.80", "9,80")
    (session / "mtx.txt").write_text("\n".join(text) + "\n")
    message = ingest_fails(session, "reference")
    # Two '//' lines and the column header: row 5 is on line 9.
    assert message.endswith("mtx.txt, line 9: column 'Acc_Z' holds '9,80'; expected a number")


def test_truncated_last_line(session: Path) -> None:
    lines = log_lines()
    lines[-1] = lines[-1][:14]
    write(session, lines, end="")
    message = ingest_fails(session)
    assert re.search(
        rf"rotation3d\.csv, line {ROWS + 1}: the last line is truncated \(\d of 11 cells\); "
        "expected 11 cells as in the header",
        message,
    )


def test_time_going_backwards(session: Path) -> None:
    lines = log_lines()
    lines[30] = lines[30].replace("0.2900,", "0.2000,", 1)
    write(session, lines)
    message = ingest_fails(session)
    assert message.endswith(
        "rotation3d.csv, line 31: t_s 0.2 s is earlier than 0.28 s on line 30; "
        "expected non-decreasing receiver time t_s"
    )


def test_duplicated_seq(session: Path) -> None:
    lines = log_lines()
    lines[12] = lines[12].replace(",11,", ",10,", 1)  # row 11 repeats the seq of row 10
    write(session, lines)
    message = ingest_fails(session)
    assert message.endswith(
        "rotation3d.csv, line 13: seq 10 repeats the seq of line 12 (duplicated packet); "
        "expected each packet once, in order (seq increasing modulo 65536)"
    )


def test_out_of_order_seq(session: Path) -> None:
    lines = log_lines()
    lines[7] = lines[7].replace(",6,", ",4,", 1)  # row 6 carries seq 4, after 5
    write(session, lines)
    message = ingest_fails(session)
    assert message.endswith(
        "rotation3d.csv, line 8: seq 4 goes back from 5 on line 7 (out-of-order packet); "
        "expected each packet once, in order (seq increasing modulo 65536)"
    )


def test_seq_beyond_16_bits(session: Path) -> None:
    lines = log_lines()
    lines[25] = lines[25].replace(",24,", ",65536,", 1)
    write(session, lines)
    message = ingest_fails(session)
    assert message.endswith(
        "rotation3d.csv, line 26: seq 65536; expected a 16-bit packet counter in 0..65535"
    )


def test_time_not_finite(session: Path) -> None:
    lines = log_lines()
    lines[33] = lines[33].replace("0.3200,", "inf,", 1)
    write(session, lines)
    message = ingest_fails(session)
    assert message.endswith(
        "rotation3d.csv, line 34: t_s is inf; expected a finite receiver time in s"
    )


def test_blank_line(session: Path) -> None:
    lines = log_lines()
    lines[5] = ""
    write(session, lines)
    message = ingest_fails(session)
    assert message.endswith(
        "rotation3d.csv, line 6: an empty line; expected one row of samples per line "
        "(no blank lines)"
    )


def test_one_mag_cell_missing(session: Path) -> None:
    lines = log_lines()
    lines[21] = lines[21].replace(",355,", ",,", 1)  # row 20: mag_y empty, mag_x, mag_z filled
    write(session, lines)
    message = ingest_fails(session)
    assert message.endswith(
        "rotation3d.csv, line 22: mag_y empty but not the other mag_x/mag_y/mag_z cells; "
        "expected all three magnetometer cells filled (fresh sample) or all three empty"
    )


def test_a_sensor_without_samples_is_reported_before_a_later_order_problem(session: Path) -> None:
    # Two problems: the whole-file one is reported, as when the table is checked at once.
    lines = [HEADER] + [",".join(line.split(",")[:8]) + ",,," for line in log_lines()[1:]]
    lines[30] = lines[30].replace("0.2900,", "0.2000,", 1)
    write(session, lines)
    message = ingest_fails(session)
    assert f"rotation3d.csv: column 'mag_x' is empty on every row (lines 2-{ROWS + 1})" in message


def test_all_mag_cells_empty(session: Path) -> None:
    lines = [HEADER] + [",".join(line.split(",")[:8]) + ",,," for line in log_lines()[1:]]
    write(session, lines)
    message = ingest_fails(session)
    assert f"rotation3d.csv: column 'mag_x' is empty on every row (lines 2-{ROWS + 1})" in message
    assert "expected values in it" in message


def test_whole_acc_column_empty(session: Path) -> None:
    lines = log_lines()
    lines[1:] = [re.sub(r"^([^,]*,[^,]*,[^,]*,)[^,]*", r"\1", line) for line in lines[1:]]
    write(session, lines)
    message = ingest_fails(session)
    assert f"rotation3d.csv: column 'acc_y' is empty on every row (lines 2-{ROWS + 1})" in message


def test_empty_file(session: Path) -> None:
    (session / "rotation3d.csv").write_text("")
    message = ingest_fails(session)
    assert message.endswith(f"rotation3d.csv: the file is empty; expected the header {HEADER}")


def test_header_only(session: Path) -> None:
    write(session, [HEADER])
    message = ingest_fails(session)
    assert message.endswith(
        "rotation3d.csv, line 2: no data rows after the header; "
        "expected at least one row of samples"
    )


@pytest.mark.slow
def test_workflow_rule_fails_and_leaves_no_parquet(session: Path, tmp_path: Path) -> None:
    lines = log_lines()
    lines[17] = lines[17].replace(",-277,", ",-2x7,")
    write(session, lines)
    work = tmp_path / "work"
    work.mkdir()
    for name in ("Snakefile", "workflow", "config", "data"):  # config.yaml names data/demo
        os.symlink(REPO / name, work / name)
    (tmp_path / "config.yaml").write_text(f"datasets:\n  broken: {session}\n")
    snakemake = shutil.which("snakemake") or pytest.skip("snakemake executable not found")
    target = "results/broken/ingest/rotation3d.parquet"
    run = subprocess.run(
        [snakemake, target, "--cores", "1", "--configfile", str(tmp_path / "config.yaml")],
        check=False,
        cwd=work,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode != 0
    assert not (work / target).exists()
    assert list((work / "results/broken/ingest").glob("*")) == []
    # It failed for the right reason: the ingest job ran and logged the one clear message.
    log = work / "results/broken/logs/ingest/rotation3d.log"
    assert log.is_file(), f"the ingest job did not run; snakemake said:\n{run.stderr[-3000:]}"
    assert "rotation3d.csv, line 18: column 'gyr_x' holds '-2x7'" in log.read_text()
    # The terminal shows the message, not a traceback (that stays in the log).
    assert "ingest of rotation3d: " in run.stderr and "rotation3d.csv, line 18" in run.stderr
    assert "Traceback" not in run.stderr
