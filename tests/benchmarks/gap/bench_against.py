"""CPU time of the demo's gap diagnosis: this checkout against another commit, in one run.

Run: ``python tests/benchmarks/gap/bench_against.py REV [--rounds 2]``. A detached git worktree
of ``REV`` is made in a temporary folder; the diagnosis of ``data/demo`` (ingested in process,
default settings) runs in a fresh interpreter for ``REV`` and for this checkout, alternately
(ABAB...), so that a change of the machine's load touches both. Prints each run's CPU time
(``time.process_time``, less sensitive to other jobs than the wall time, which is printed too),
the median ratio this/REV, and whether both found the same effects.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]

RUN = """
import json, sys, time
from imucal.constants import IMU_RECORDINGS
from imucal.gap import diagnose
from imucal.ingest import ingest_recording
from imucal.io.dataset import read_dataset
from imucal.pipeline.full import PipelineOptions
info = read_dataset(sys.argv[1])
tables = {r: ingest_recording(p, r, info, "bench")[0] for r, p in info.recordings.items()}
imu = {r: t for r, t in tables.items() if r in IMU_RECORDINGS}
t, c = time.perf_counter(), time.process_time()
d = diagnose(imu, tables.get("reference"), PipelineOptions.of_dataset(info), dataset="demo")
print(json.dumps({"cpu_s": time.process_time() - c, "wall_s": time.perf_counter() - t,
                  "explained": d["explained"]}))
"""


def _run(checkout: Path) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", RUN, str(REPO / "data" / "demo")],
        cwd=checkout, env={"PYTHONPATH": str(checkout), "PATH": "/usr/bin:/bin"},
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rev")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "old"
        subprocess.run(
            ["git", "-C", str(REPO), "worktree", "add", "--detach", str(old), args.rev],
            check=True, capture_output=True,
        )  # fmt: skip
        try:
            runs = {"old": [], "new": []}
            for _ in range(args.rounds):
                for name, checkout in (("old", old), ("new", REPO)):
                    runs[name].append(_run(checkout))
                    r = runs[name][-1]
                    print(f"{name}: cpu {r['cpu_s']:.1f} s, wall {r['wall_s']:.1f} s, "
                          f"explained {r['explained']}")  # fmt: skip
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(old)])
    ratio = statistics.median(
        n["cpu_s"] / o["cpu_s"] for o, n in zip(runs["old"], runs["new"], strict=True)
    )
    same = all(o["explained"] == n["explained"] for o, n in zip(runs["old"], runs["new"]))
    print(f"CPU time this/{args.rev}: {ratio:.2f} (median of {args.rounds}); same effects: {same}")


if __name__ == "__main__":
    main()
