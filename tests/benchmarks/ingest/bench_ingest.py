"""Benchmark of the ingest: raw CSV -> checked SI parquet, against a bare pyarrow CSV read.

A script, not a test (speed is measured, never asserted). It writes a synthetic log of
``--rows`` packets (100 Hz, seq wrapping at 65536, 10 Hz magnetometer, a ``temp_c`` column)
into a temporary folder, then times, in the same run and alternately:

- ``bare``: ``pyarrow.csv.read_csv(path)`` with default options (no checks, nothing written);
- ``ingest``: :func:`imucal.ingest.ingest_recording` + :func:`imucal.io.write_recording`
  (typed read, format and order checks, SHA-256, conversion to SI, atomic parquet write).

It prints rows/s of both (best of ``--repeat``) and their ratio; the target is ingest/bare
>= 0.5. Run: ``python tests/benchmarks/ingest/bench_ingest.py [--rows 2000000]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.csv as pacsv

from imucal.columns import ACC, GYR, MAG, RAW_COLUMNS, SEQ_MODULUS
from imucal.ingest import ingest_recording
from imucal.io import write_recording
from imucal.io.dataset import read_dataset

SENSITIVITY = {"acc": 0.00239501953125, "gyr": 0.0002664624812205083, "mag": 0.001}


def write_log(path: Path, rows: int, seed: int = 0) -> None:
    """Write a synthetic raw log of ``rows`` packets in the native CSV format."""
    rng = np.random.default_rng(seed)
    chunk = 500_000
    with path.open("w") as f:
        f.write(",".join((*RAW_COLUMNS, "temp_c")) + "\n")
        for start in range(0, rows, chunk):
            i = np.arange(start, min(start + chunk, rows))
            counts = rng.integers(-4096, 4096, size=(i.size, 6))
            mag = rng.integers(-700, 700, size=(i.size, 3))
            temp = 25.0 + 0.1 * rng.standard_normal(i.size)
            lines = []
            for k, row in enumerate(i):
                m = ",".join(map(str, mag[k])) if row % 10 == 0 else ",,"
                acc_gyr = ",".join(map(str, counts[k]))
                lines.append(f"{row * 0.01:.4f},{row % SEQ_MODULUS},{acc_gyr},{m},{temp[k]:.2f}\n")
            f.writelines(lines)


def write_dataset_yaml(folder: Path) -> None:
    sens = ", ".join(f"{k}: {v!r}" for k, v in SENSITIVITY.items())
    (folder / "dataset.yaml").write_text(
        "name: bench\ngravity_m_s2: 9.81\n"
        f"sensitivity: {{{sens}}}\n"
        "recordings: {rotation3d: log.csv, cube: log.csv}\n"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=2_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        log = folder / "log.csv"
        t0 = time.perf_counter()
        write_log(log, args.rows)
        write_dataset_yaml(folder)
        dataset = read_dataset(folder)
        print(
            f"wrote {args.rows} rows ({log.stat().st_size / 1e6:.0f} MB) in "
            f"{time.perf_counter() - t0:.1f} s"
        )
        bare, ingest = [], []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            table = pacsv.read_csv(log)
            bare.append(time.perf_counter() - t0)
            assert table.num_rows == args.rows
            del table
            t0 = time.perf_counter()
            table, metadata = ingest_recording(log, "rotation3d", dataset, "bench")
            write_recording(table, folder / "log.parquet", metadata)
            ingest.append(time.perf_counter() - t0)
            assert len(table) == args.rows
            assert np.isnan(table[list(MAG)].to_numpy()).sum() == 3 * (
                args.rows - -(-args.rows // 10)
            )
            assert not np.isnan(table[[*ACC, *GYR]].to_numpy()).any()
            del table
        rate_bare = args.rows / min(bare)
        rate_ingest = args.rows / min(ingest)
        print(
            f"bare pyarrow.csv.read_csv: {rate_bare:12,.0f} rows/s  (best {min(bare):.3f} s "
            f"of {', '.join(f'{t:.3f}' for t in bare)})"
        )
        print(
            f"imucal ingest to parquet:  {rate_ingest:12,.0f} rows/s  (best {min(ingest):.3f} "
            f"s of {', '.join(f'{t:.3f}' for t in ingest)})"
        )
        print(f"ratio ingest/bare: {rate_ingest / rate_bare:.2f} (target >= 0.5)")


if __name__ == "__main__":
    main()
