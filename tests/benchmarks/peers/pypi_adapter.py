"""Run the PyPI ``imucal`` (mad-lab-fau, Ferraris method) on one session; executed by the peers venv.

Usage: ``<venv>/bin/python pypi_adapter.py <session> <data_dir> <expected_angle_deg> <out_prefix>``
with ``<session>`` 'example' (example_ferraris_session.csv + section list, m/s^2 and deg/s,
102.4 Hz) or 'annotated' (annotated_session.csv, counts, 204.8 Hz). Writes ``<out_prefix>.json``
(matrices, biases, run time) and ``<out_prefix>.npz`` (the whole session calibrated by the tool's
own ``calibrate``, rows in the order of the file sorted by sample index).
"""

import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from imucal import FerrarisCalibration, ferraris_regions_from_df, ferraris_regions_from_section_list

ACC = ["acc_x", "acc_y", "acc_z"]
GYR = ["gyr_x", "gyr_y", "gyr_z"]
REPEATS = 20


def main() -> None:
    session, data_dir, expected_angle, out_prefix = sys.argv[1:5]
    data_dir = Path(data_dir)
    if session == "example":
        data = pd.read_csv(data_dir / "example_ferraris_session.csv", header=0, index_col=0)
        sections = pd.read_json(data_dir / "example_ferraris_session_list.json").T
        regions = ferraris_regions_from_section_list(data, sections)
        rate_hz, acc_unit, gyr_unit = 102.4, "m/s^2", "deg/s"
        full = data
    else:
        table = pd.read_csv(data_dir / "annotated_session.csv", header=0, index_col=[0, 1])
        regions = ferraris_regions_from_df(table)
        rate_hz, acc_unit, gyr_unit = 204.8, "a.u.", "a.u."
        full = table.reset_index().sort_values("samples")
    cal = FerrarisCalibration(expected_angle=float(expected_angle))
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        info = cal.compute(
            regions, sampling_rate_hz=rate_hz, from_acc_unit=acc_unit, from_gyr_unit=gyr_unit
        )
        times.append(time.perf_counter() - t0)
    acc, gyr = info.calibrate(
        full[ACC].to_numpy(float), full[GYR].to_numpy(float), acc_unit=acc_unit, gyr_unit=gyr_unit
    )
    import imucal

    out = {
        k: np.asarray(getattr(info, k)).tolist()
        for k in ("K_a", "R_a", "b_a", "K_g", "R_g", "K_ga", "b_g")
    }
    out.update(
        version=imucal.__version__ if hasattr(imucal, "__version__") else "unknown",
        expected_angle_deg=float(expected_angle),
        grav=cal.grav,
        compute_time_s_min=min(times),
        compute_time_s_median=float(np.median(times)),
        acc_unit_out=info.acc_unit,
        gyr_unit_out=info.gyr_unit,
    )
    Path(out_prefix + ".json").write_text(json.dumps(out, indent=1))
    np.savez(out_prefix + ".npz", acc=acc, gyr=gyr)


if __name__ == "__main__":
    main()
