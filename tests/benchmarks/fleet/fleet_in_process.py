"""The fleet report of a sample sheet with each session calibrated in process.

    python tests/benchmarks/fleet/fleet_in_process.py SHEET OUT_DIR

Runs the paper's chain in process (:func:`imucal.pipeline.full.calibrate_session`, the code
the rules run stage by stage) on every full-protocol session of the sheet, then the fleet
summary, figures and report of the ``fleet_report`` rule, into ``OUT_DIR``. It shows the report
of a large simulated fleet without the ~17 jobs per session of the workflow (each pays the
interpreter's start-up); the workflow's ``fleet`` target is the way to run a real fleet.
"""

from __future__ import annotations

import sys
from pathlib import Path

from imucal.constants import IMU_RECORDINGS
from imucal.fleet import read_sample_sheet, summarize_fleet
from imucal.ingest import ingest_recording
from imucal.io import write_json
from imucal.io.dataset import read_dataset
from imucal.pipeline.full import PipelineOptions, calibrate_session
from imucal.plots.fleet import plot_bias_over_time, plot_fleet_parameters
from imucal.report import embed_figure
from imucal.report.fleet import render_fleet_report


def main(sheet_path: str, out_dir: str) -> None:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sheet = read_sample_sheet(sheet_path)
    calibrations, paths = {}, {}
    for row in sheet.itertuples(index=False):
        info = read_dataset(row.path)
        tables = {r: ingest_recording(p, r, info, "fleet")[0] for r, p in info.recordings.items()}
        imu = {r: t for r, t in tables.items() if r in IMU_RECORDINGS}
        fit = calibrate_session(imu, tables.get("reference"), PipelineOptions.of_dataset(info))
        paths[row.dataset] = str(out / "calibrations" / f"{row.dataset}.json")
        calibrations[row.dataset] = fit.calibration.to_dict()
        write_json(calibrations[row.dataset], paths[row.dataset])
        print(f"calibrated {row.dataset}")
    summary, table, scores = summarize_fleet(sheet, calibrations, paths, outlier_z=5.0, drift_z=3.0)
    summary = {"sheet": sheet_path, "store": str(out / "store.json"), "imucal_version": "-",
               **summary}  # fmt: skip
    table.to_csv(out / "parameters.csv", index=False)
    write_json(summary["store_index"], out / "store.json")
    write_json(summary, out / "fleet.json")
    plot_fleet_parameters(scores).savefig(out / "parameters.png", dpi=100)
    plot_bias_over_time(table).savefig(out / "drift.png", dpi=100)
    figures = {k: embed_figure(out / f"{k}.png") for k in ("parameters", "drift")}
    (out / "fleet.html").write_text(render_fleet_report(summary, figures), encoding="utf-8")
    print(f"outlier units {summary['outlier_units']}; drift rows {len(summary['drift'])}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
