"""Rule plot_segments: one recording with its segments shaded (imucal.plots.segmentation)."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording
from imucal.io.logs import log_to
from imucal.plots.figurefile import save_figure
from imucal.plots.segmentation import plot_segments

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake

log_to(snakemake.log[0])
try:
    table, _ = read_recording(snakemake.input.table)
    segments, _ = read_recording(snakemake.input.segments)
    w = snakemake.wildcards
    fig = plot_segments(
        table, segments, recording=w.recording, title=f"{w.dataset} / {w.recording}"
    )
    save_figure(fig, snakemake.output.png)
except Exception:
    logging.exception("segments plot of %s failed", snakemake.input.table)
    raise
