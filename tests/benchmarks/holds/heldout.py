"""Leave-one-pose-out |a| - g of the accelerometer cube fit on a dataset's segmented poses.

Usage (after the workflow's segment rule):
    python tests/benchmarks/holds/heldout.py results/tomisuarez2_imu [results/ck_explorer ...]
Prints, per dataset, the poses used and the RMS and max of the raw ``|mean| - g`` and of the
held-out ``|S'(mean - o)| - g`` (each pose against the fit on the others), m/s^2, and of the
held-out error over the standard deviation the held-out fit's reported covariance predicts
(``z``, about 1 when the covariance is honest).
"""

import sys
from pathlib import Path

import numpy as np

from imucal.columns import ACC
from imucal.fits.accelerometer import heldout_errors
from imucal.io import read_recording, read_segments
from imucal.io.dataset import read_dataset

for folder in map(Path, sys.argv[1:]):
    segments = read_segments(folder / "segments.parquet")
    rows = segments[segments["recording"] == "poses"]
    table, _ = read_recording(folder / "ingest" / "poses.parquet")
    acc = table[list(ACC)].to_numpy(dtype=float)
    positions = [acc[a:b] for a, b in zip(rows["start_index"], rows["end_index"])]
    _, meta = read_recording(folder / "segments.parquet")
    gravity = read_dataset(Path("data/real") / folder.name).gravity_m_s2
    held = heldout_errors(positions, gravity)
    print(f"{folder.name}: {len(positions)} poses; note: {meta.get('notes', {}).get('poses', '-')}")
    for name, e in (("raw", held.before), ("held-out", held.after), ("z", held.z)):
        e = e[np.isfinite(e)]
        print(
            f"  {name:9s} RMS {np.sqrt(np.mean(e**2)):.4f}  max {np.abs(e).max():.4f} (n={e.size})"
        )
