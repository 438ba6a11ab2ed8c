"""Held-out errors of the real recordings against what their reported covariance predicts.

Usage (after `snakemake --cores 2 real`):
    python tests/benchmarks/uncertainty/heldout_real.py results/kyle_ak_imu_tk results/ck_explorer
        results/tomisuarez2_imu results/mad_lab_ferraris results/sunsided_sensor_fusion

Per dataset, what its partial calibration offers:
- the cube fit (acc_cube): each pose against the fit on the others, ``z = error / predicted
  std`` (the held-out fit's inflated covariance and the pose's noise); RMS of z and the share
  within 1.96 (95 % when honest);
- the known-orientation fit (acc_known_orientation): each face against the fit on the other
  five, ``z2`` (chi-square with 3 dof when honest, 3 F(3, 3) with the placement tilt estimated
  from 3 residuals: median 3, 95 % below 27.8);
- the gyroscope bias of the static recording: the bias of its first half against that of its
  second, each with its reported std (the wander's variance added where the blocks show it),
  ``z = (b1 - b2) / sqrt(s1^2 + s2^2)`` per axis.
"""

import json
import sys
from pathlib import Path

import numpy as np

from imucal.columns import GYR
from imucal.fits.gyroscope import estimate_bias
from imucal.io import read_recording
from imucal.pipeline.stages import gyr_bias_value, plain

for folder in map(Path, sys.argv[1:]):
    print(folder.name)
    acc = json.loads((folder / "partial" / "acc.json").read_text())
    cube = acc.get("acc_cube", {})
    if "heldout_predicted_std_m_s2" in cube:
        z = np.array(cube["heldout_error_after_m_s2"], float) / np.array(
            cube["heldout_predicted_std_m_s2"], float
        )
        z = z[np.isfinite(z)]
        print(
            f"  cube, {z.size} poses held out: RMS z {np.sqrt(np.mean(z**2)):.2f}, "
            f"|z| < 1.96 in {np.mean(np.abs(z) < 1.96):.0%} (chi2/dof of the fit "
            f"{cube['chi2'] / max(cube['dof'], 1):.3g}, dof {cube['dof']})"
        )
    faces = acc.get("acc_known_orientation", {})
    if "heldout_z2" in faces:
        z2 = np.array(faces["heldout_z2"], float)
        print(f"  faces held out: z2 {np.round(z2, 2).tolist()} (median {np.median(z2):.2f})")
    static = folder / "ingest" / "static.parquet"
    if static.exists():
        table, _ = read_recording(static)
        gyr = table[list(GYR)].to_numpy(float)
        gyr = gyr[np.all(np.isfinite(gyr), axis=1)]
        half = len(gyr) // 2
        parts = [plain(estimate_bias(part)) for part in (gyr[:half], gyr[half:])]
        (b1, s1), (b2, s2) = (gyr_bias_value(p, "ls") for p in parts)
        z = (b1 - b2) / np.sqrt(s1**2 + s2**2)
        print(f"  gyroscope bias, static halves: z {np.round(z, 2).tolist()}")
