"""Rule noise: Allan deviation and IEEE 952 noise terms of the static recording."""

from functools import partial
from typing import TYPE_CHECKING

from imucal.io import read_recording_column, recording_column_names, write_json
from imucal.io.logs import log_to
from imucal.noise import characterise_noise
from imucal.pipeline.outcome import stage_guard
from imucal.plots.figurefile import save_figure
from imucal.plots.noise import plot_allan

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
p = snakemake.params

with stage_guard("noise", snakemake.output):
    path = snakemake.input.recording
    noise = characterise_noise(
        partial(read_recording_column, path), recording_column_names(path),
        recording=p.recording, window_s=p.window_s, min_duration_s=p.min_duration_s,
        level=p.level,
    )  # fmt: skip
    write_json(noise, snakemake.output.noise)
    save_figure(plot_allan(noise), snakemake.output.figure)
