"""Cost of the gap diagnosis against the length of the static recording, in one run.

Run: ``python tests/benchmarks/gap/bench_static_length.py [--static-s 86400] [--rounds 1]``.
A session like the demo (preset ``demo``, seed 2014) but with a static recording of
``--static-s`` seconds at 100 Hz is simulated and ingested into a temporary folder (not
timed); then the diagnosis of that session and of ``data/demo`` (both ingested, 20 replicas,
the workflow's way: the recordings read from their parquet files, the long static one batch
by batch) run each in a fresh interpreter, alternately (ABAB...), so that a change of the
machine's load touches both. Each child reports its own CPU time (user + sys,
``resource.getrusage``), wall time and peak RSS, from its start (imports and reading included); printed are the median ratios long/demo of
CPU and wall time, the peak RSS of the long session and whether both explained the same
effects (the demo's are packet loss and the reference's clock offset; the long session has
the same).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]

#: Simulate and ingest a session into argv[2] (dataset folder argv[1]).
PREPARE = """
import sys
from pathlib import Path
from imucal.ingest import ingest_recording
from imucal.io import write_recording
from imucal.io.dataset import read_dataset
info = read_dataset(sys.argv[1])
out = Path(sys.argv[2]); out.mkdir(parents=True, exist_ok=True)
for r, p in info.recordings.items():
    table, meta = ingest_recording(p, r, info, info.name)
    write_recording(table, out / f"{r}.parquet", meta)
"""

#: The diagnosis of an ingested session (dataset folder argv[1], parquet folder argv[2]).
DIAGNOSE = """
import json, resource, sys, time
from pathlib import Path
from imucal.constants import IMU_RECORDINGS
from imucal.gap import diagnose
from imucal.gap.blocks import read_decimated_static
from imucal.io import read_recording
from imucal.io.dataset import read_dataset
from imucal.pipeline.full import PipelineOptions
wall = time.perf_counter()
info = read_dataset(sys.argv[1])
files = {p.stem: p for p in Path(sys.argv[2]).glob("*.parquet")}
imu = {r: read_recording(files[r])[0] for r in IMU_RECORDINGS if r in files and r != "static"}
imu["static"], blocks = read_decimated_static(files["static"])
reference = read_recording(files["reference"])[0] if "reference" in files else None
d = diagnose(imu, reference, PipelineOptions.of_dataset(info), dataset=info.name,
             static_blocks=blocks)
use = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"wall_s": time.perf_counter() - wall, "explained": d["explained"],
                  "cpu_s": use.ru_utime + use.ru_stime, "peak_rss_gb": use.ru_maxrss / 1e6,
                  "static_rows": blocks.n_rows if blocks else len(imu["static"])}))
"""


def _child(code: str, *args: str) -> dict:
    """Run ``code`` in a fresh interpreter; the JSON of its last stdout line."""
    out = subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=REPO, env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"},
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    lines = out.stdout.strip().splitlines()
    return json.loads(lines[-1]) if lines else {}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--static-s", type=float, default=86400.0)
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        long_data, long_ingested = Path(tmp) / "long", Path(tmp) / "long_ingested"
        demo_ingested = Path(tmp) / "demo_ingested"
        t = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "imucal.cli", "simulate", str(long_data), "--preset", "demo",
             "--seed", "2014", "--static-s", str(args.static_s), "--name", "long"],
            cwd=REPO, env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}, check=True,
            capture_output=True,
        )  # fmt: skip
        _child(PREPARE, str(long_data), str(long_ingested))
        _child(PREPARE, str(REPO / "data" / "demo"), str(demo_ingested))
        print(f"simulated and ingested in {time.perf_counter() - t:.0f} s")
        runs = {"long": [], "demo": []}
        for _ in range(args.rounds):
            for name, data, ingested in (("long", long_data, long_ingested),
                                         ("demo", REPO / "data" / "demo", demo_ingested)):  # fmt: skip
                r = _child(DIAGNOSE, str(data), str(ingested))
                runs[name].append(r)
                print(f"{name}: {r['static_rows']} static rows, cpu {r['cpu_s']:.1f} s, "
                      f"wall {r['wall_s']:.1f} s, peak RSS {r['peak_rss_gb']:.2f} GB, "
                      f"explained {r['explained']}")  # fmt: skip
    ratio = {
        k: statistics.median(a[k] / b[k] for a, b in zip(runs["long"], runs["demo"], strict=True))
        for k in ("cpu_s", "wall_s")
    }
    same = all(a["explained"] == b["explained"] for a, b in zip(runs["long"], runs["demo"]))
    print(f"long/demo: cpu {ratio['cpu_s']:.2f}, wall {ratio['wall_s']:.2f} (median of "
          f"{args.rounds}); largest peak RSS of the long session "
          f"{max(r['peak_rss_gb'] for r in runs['long']):.2f} GB; "
          f"same effects: {same}")  # fmt: skip


if __name__ == "__main__":
    main()
