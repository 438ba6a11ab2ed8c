"""Time of one gap diagnosis (in process, no Snakemake), against the calibration alone.

Run: ``PYTHONPATH=. python tests/benchmarks/gap/bench_gap.py data/demo [replicas]``. Prints the
wall time of the pipeline fit alone (baseline) and of the whole diagnosis, and their ratio.
"""

from __future__ import annotations

import sys
import time

from imucal.constants import IMU_RECORDINGS
from imucal.gap import DiagnosisSettings, diagnose
from imucal.ingest import ingest_recording
from imucal.io.dataset import read_dataset
from imucal.pipeline.full import PipelineOptions, calibrate_session


def main(folder: str, replicas: int = 20) -> None:
    info = read_dataset(folder)
    tables = {r: ingest_recording(p, r, info, "bench")[0] for r, p in info.recordings.items()}
    imu = {r: t for r, t in tables.items() if r in IMU_RECORDINGS}
    options = PipelineOptions.of_dataset(info)
    t0 = time.perf_counter()
    calibrate_session(imu, tables.get("reference"), options)
    base = time.perf_counter() - t0
    t0 = time.perf_counter()
    settings = DiagnosisSettings(replicas=replicas)
    result = diagnose(imu, tables.get("reference"), options, dataset=info.name, settings=settings)
    total = time.perf_counter() - t0
    print(f"fit alone {base:.2f} s; diagnosis ({replicas} replicas) {total:.1f} s "
          f"(null {result['timing_s']['null']:.1f} s); ratio {total / base:.0f}; "
          f"explained {result['explained']}")  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1], *(int(a) for a in sys.argv[2:3]))
