"""Rule validation_figures: module vs reference magnitudes (Fig. 20) and the correlation."""

from typing import TYPE_CHECKING

from imucal.io import read_calibration, read_recording
from imucal.io.logs import log_to
from imucal.pipeline.outcome import read_artifact, stage_guard
from imucal.pipeline.stages import plot_validation
from imucal.plots.figurefile import save_figure

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])

with stage_guard("validation_figures", snakemake.output):
    rotation3d, metadata = read_recording(snakemake.input.rotation3d)
    figures = plot_validation(
        rotation3d,
        metadata,
        read_recording(snakemake.input.reference)[0],
        read_calibration(snakemake.input.calibration),
        read_artifact(snakemake.input.validation),
    )
    save_figure(figures["validation_magnitudes"], snakemake.output.magnitudes)
    save_figure(figures["validation_xcorr"], snakemake.output.xcorr)
