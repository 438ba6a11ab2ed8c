"""Rule phase_figures: accelerometer and gyroscope phases before/after alignment (Figs. 11-13, 18-19)."""

from typing import TYPE_CHECKING

from imucal.io import read_recording, read_segments
from imucal.io.logs import log_to
from imucal.pipeline.outcome import read_artifact, stage_guard
from imucal.pipeline.stages import plot_phases
from imucal.plots.figurefile import save_figure

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])

with stage_guard("phase_figures", snakemake.output):
    rotation3d, _ = read_recording(snakemake.input.rotation3d)
    segments = read_segments(snakemake.input.segments)
    for sensor in ("acc", "gyr"):
        figure = plot_phases(
            rotation3d, segments, sensor, read_artifact(snakemake.input[sensor])["calibration"]
        )
        save_figure(figure, snakemake.output[sensor])
