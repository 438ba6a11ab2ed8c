"""Rule report: the self-contained HTML lab report of one dataset."""

from pathlib import Path
from typing import TYPE_CHECKING

from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.report import ReportInputs, build_report_context, render_report
from imucal.report.provenance import workflow_commit

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
inputs = ReportInputs(
    dataset=snakemake.wildcards.dataset,
    summary=snakemake.input.summary,
    calibration=snakemake.input.calibration,
    mag_result=snakemake.input.mag,
    acc_result=snakemake.input.acc,
    gyr_result=snakemake.input.gyr,
    validation=snakemake.input.get("validation"),
    tables=snakemake.input.get("tables"),
    stages=snakemake.input.stages,
    figures=list(snakemake.input.figures)
    + (
        sorted(Path(snakemake.input.figure_dir).glob("*.png"))
        if "figure_dir" in snakemake.input.keys()
        else []
    ),  # noqa: SIM118
    benchmarks=list(snakemake.input.benchmarks),
    config=dict(snakemake.params.settings),
    git_commit=workflow_commit(snakemake.scriptdir),
    imucal_version=snakemake.params.imucal_version,
    report_path=snakemake.output.html,
    gap=list(snakemake.input.gap) if "gap" in snakemake.input.keys() else None,  # noqa: SIM118
    noise=list(snakemake.input.noise) if "noise" in snakemake.input.keys() else None,  # noqa: SIM118
    terms=[snakemake.input.terms, snakemake.input.gap_after]
    if "terms" in snakemake.input.keys()  # noqa: SIM118
    else None,
    temperature_holdout=snakemake.input.get("temperature_holdout"),
    consistency=snakemake.input.get("consistency"),
    logs=list(snakemake.input.logs),
    dataset_folder=Path(snakemake.input.dataset_yaml).parent,
    simulated=read_dataset(Path(snakemake.input.dataset_yaml).parent).simulated,
)
Path(snakemake.output.html).write_text(
    render_report(build_report_context(inputs)), encoding="utf-8"
)
