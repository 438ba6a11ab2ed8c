"""Benchmark of the ingest: raw CSV -> checked SI parquet, against a bare pyarrow CSV read.

A script, not a test (speed is measured, never asserted). It writes a synthetic log of
``--rows`` packets (at ``--rate-hz``, default 100 Hz; seq wrapping at 65536, a magnetometer
sample every 10th packet, a ``temp_c`` column) into a temporary folder, then times, in the same
run and alternately:

- ``bare``: ``pyarrow.csv.read_csv(path)`` with default options (no checks, nothing written);
- ``ingest``: :func:`imucal.ingest.ingest_to_parquet`, what the ingest rule runs (streamed:
  typed read in batches, format, order and range checks, SHA-256 on the stream, conversion to
  SI, parquet row groups written atomically).

It prints rows/s of both (best of ``--repeat``) and their ratio (target ingest/bare >= 0.8),
and the peak RSS of the process. Run:
``python tests/benchmarks/ingest/bench_ingest.py [--rows 2000000]``.

``--stream-only`` skips the bare read (which holds the whole table in memory) and the checks
against it, so that the peak RSS is the streaming ingest's own (the synthetic log is written
in chunks of 1 M rows first, by the same process): e.g. ``--rows 86400000 --rate-hz 1000
--repeat 1 --stream-only --tmp /tmp`` for 24 h at 1 kHz (a 4.9 GB file, deleted at the end).
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from imucal.columns import ACC, GYR, MAG, RAW_COLUMNS, SEQ_MODULUS
from imucal.ingest import ingest_to_parquet
from imucal.io.dataset import read_dataset

SENSITIVITY = {"acc": 0.00239501953125, "gyr": 0.0002664624812205083, "mag": 0.001}


def write_log(path: Path, rows: int, rate_hz: float = 100.0, seed: int = 0) -> None:
    """Write a synthetic raw log of ``rows`` packets at ``rate_hz`` in the native CSV format."""
    rng = np.random.default_rng(seed)
    chunk = 1_000_000
    names = (*RAW_COLUMNS, "temp_c")
    with path.open("wb") as f:
        f.write((",".join(names) + "\n").encode())
        options = pacsv.WriteOptions(include_header=False)
        for start in range(0, rows, chunk):
            i = np.arange(start, min(start + chunk, rows))
            counts = rng.integers(-4096, 4096, size=(i.size, 6))
            mag = rng.integers(-700, 700, size=(i.size, 3))
            fresh = i % 10 == 0  # 10 Hz magnetometer: empty cells on the other rows
            columns = [np.round(i / rate_hz, 4), i % SEQ_MODULUS, *counts.T]
            columns += [pa.array(m, mask=~fresh) for m in mag.T]
            columns.append(np.round(25.0 + 0.1 * rng.standard_normal(i.size), 2))
            pacsv.write_csv(pa.table(columns, names=names), f, options)


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
    parser.add_argument("--rate-hz", type=float, default=100.0, help="packet rate of the log")
    parser.add_argument("--stream-only", action="store_true")
    parser.add_argument("--tmp", default=None, help="folder for the temporary files")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(dir=args.tmp) as tmp:
        folder = Path(tmp)
        log = folder / "log.csv"
        t0 = time.perf_counter()
        write_log(log, args.rows, args.rate_hz)
        write_dataset_yaml(folder)
        dataset = read_dataset(folder)
        print(
            f"wrote {args.rows} rows ({log.stat().st_size / 1e6:.0f} MB) in "
            f"{time.perf_counter() - t0:.1f} s"
        )
        out = folder / "log.parquet"
        bare, ingest = [], []
        for _ in range(args.repeat):
            if not args.stream_only:
                t0 = time.perf_counter()
                table = pacsv.read_csv(log)
                bare.append(time.perf_counter() - t0)
                assert table.num_rows == args.rows
                del table
            t0 = time.perf_counter()
            ingest_to_parquet(log, "rotation3d", dataset, "bench", out)
            ingest.append(time.perf_counter() - t0)
            assert pq.read_metadata(out).num_rows == args.rows
        if not args.stream_only:
            mag = pq.read_table(out, columns=[*MAG, *ACC, *GYR])
            assert mag.column(MAG[0]).null_count == args.rows - -(-args.rows // 10)
            assert all(mag.column(c).null_count == 0 for c in (*ACC, *GYR))
            del mag
        rate_ingest = args.rows / min(ingest)
        print(
            f"imucal ingest to parquet:  {rate_ingest:12,.0f} rows/s  (best {min(ingest):.3f} "
            f"s of {', '.join(f'{t:.3f}' for t in ingest)})"
        )
        if not args.stream_only:
            rate_bare = args.rows / min(bare)
            print(
                f"bare pyarrow.csv.read_csv: {rate_bare:12,.0f} rows/s  (best {min(bare):.3f} s "
                f"of {', '.join(f'{t:.3f}' for t in bare)})"
            )
            print(f"ratio ingest/bare: {rate_ingest / rate_bare:.2f} (target >= 0.8)")
        peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"peak RSS of this process: {peak_mb:,.0f} MB")


if __name__ == "__main__":
    main()
