"""Rule fleet_report: parameters across units, drift between calibrations, calibration store."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.fleet import read_sample_sheet, summarize_fleet
from imucal.io import read_json, write_json
from imucal.io.logs import log_to
from imucal.plots.figurefile import save_figure
from imucal.plots.fleet import plot_bias_over_time, plot_fleet_parameters
from imucal.report import embed_figure
from imucal.report.fleet import render_fleet_report

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
p = snakemake.params
out = snakemake.output
sheet = read_sample_sheet(p.sheet)
paths = {name: str(Path(path).resolve()) for name, path in snakemake.input.items()}
summary, table, scores = summarize_fleet(
    sheet,
    {name: read_json(path) for name, path in paths.items()},
    paths,
    outlier_z=p.outlier_z,
    drift_z=p.drift_z,
)
summary = {"sheet": p.sheet, "store": out.store, "imucal_version": p.imucal_version, **summary}
table.to_csv(out.parameters, index=False)
write_json(summary["store_index"], out.store)
write_json(summary, out.summary)
save_figure(plot_fleet_parameters(scores), out.parameters_figure)
save_figure(plot_bias_over_time(table), out.drift_figure)
figures = {
    "parameters": embed_figure(out.parameters_figure),
    "drift": embed_figure(out.drift_figure),
}
Path(out.html).write_text(render_fleet_report(summary, figures), encoding="utf-8")
logging.info("%d units, outliers %s", summary["n_units"], summary["outlier_units"])
