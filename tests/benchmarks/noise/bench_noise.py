"""Benchmark of the noise stage on a 24 h static at 100 Hz (8.64 M rows), against allantools.

A script, not a test (memory and speed are measured, never asserted). It writes a synthetic
static recording (parquet: ``t_s`` and nine sensor columns, white noise plus a bias random walk
on a gravity offset) into a temporary folder, then runs, each in a fresh process so that the
peak resident set sizes do not mix:

- ``allantools``: the table read whole (``pyarrow.parquet.read_table(...).to_pandas()``) and
  ``allantools.oadev(column, rate, data_type="freq", taus="octave")`` on each sensor column:
  the deviations only;
- ``noise``: :func:`imucal.noise.characterise_noise` reading one column at a time
  (:func:`imucal.io.read_recording_column`): deviations, degrees of freedom, intervals and fits.

It prints the peak RSS (MB) and wall time of both and the ratios noise / allantools.
Run: ``python tests/benchmarks/noise/bench_noise.py [--hours 24]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from imucal.columns import ACC, GYR, MAG, TIME

RATE = 100.0
COLUMNS = ACC + GYR + MAG


def write_static(path: Path, rows: int, seed: int = 0) -> None:
    """A static recording of ``rows`` samples at 100 Hz, written in chunks of 1 M rows."""
    rng = np.random.default_rng(seed)
    chunk = 1_000_000
    schema = pa.schema([(TIME, pa.float64())] + [(c, pa.float64()) for c in COLUMNS])
    walk = np.zeros(len(COLUMNS))
    with pq.ParquetWriter(path, schema) as writer:
        for start in range(0, rows, chunk):
            n = min(chunk, rows - start)
            data = {TIME: (start + np.arange(n)) / RATE}
            for j, name in enumerate(COLUMNS):
                steps = 1e-5 * rng.standard_normal(n)
                w = walk[j] + np.cumsum(steps)
                walk[j] = w[-1]
                offset = 9.81 if name == "acc_z" else 0.0
                data[name] = offset + 0.02 * rng.standard_normal(n) + w
            writer.write_table(pa.table(data, schema=schema))


def run_allantools(path: str) -> None:
    import allantools

    table = pq.read_table(path).to_pandas()
    for name in COLUMNS:
        allantools.oadev(table[name].to_numpy(), rate=RATE, data_type="freq", taus="octave")


def run_noise(path: str) -> None:
    from imucal.io import read_recording_column, recording_column_names
    from imucal.noise import characterise_noise

    characterise_noise(partial(read_recording_column, path), recording_column_names(path),
                       recording="static", window_s=None, min_duration_s=30.0, level=0.683)  # fmt: skip


def _child(kind: str, path: str) -> None:
    start = time.perf_counter()
    {"allantools": run_allantools, "noise": run_noise}[kind](path)
    seconds = time.perf_counter() - start
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: kB
    print(json.dumps({"kind": kind, "s": seconds, "max_rss_mb": rss_mb}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--child", nargs=2, metavar=("KIND", "PATH"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(*args.child)
        return
    rows = int(args.hours * 3600 * RATE)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "static.parquet"
        write_static(path, rows)
        print(
            f"{rows} rows, {len(COLUMNS)} sensor columns, {path.stat().st_size / 1e6:.0f} MB parquet"
        )
        results = {}
        for kind in ("allantools", "noise"):
            out = subprocess.run([sys.executable, __file__, "--child", kind, str(path)],
                                 capture_output=True, text=True, check=True)  # fmt: skip
            results[kind] = json.loads(out.stdout.strip().splitlines()[-1])
            print(
                f"{kind:>10}: {results[kind]['s']:7.1f} s, peak RSS {results[kind]['max_rss_mb']:7.0f} MB"
            )
    a, n = results["allantools"], results["noise"]
    print(
        f"ratios noise / allantools: time {n['s'] / a['s']:.2f}, "
        f"peak RSS {n['max_rss_mb'] / a['max_rss_mb']:.2f}"
    )


if __name__ == "__main__":
    main()
