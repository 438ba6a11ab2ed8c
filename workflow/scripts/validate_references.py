"""Rule validate_references: the calibration against the orientation references."""

from pathlib import Path
from typing import TYPE_CHECKING

from imucal.io import read_json, read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.pipeline.reference import validate_references
from imucal.plots.figurefile import save_figure
from imucal.plots.reference import plot_orientation_errors

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
references = {}
for path in snakemake.input.orientation:
    table, metadata = read_recording(path)
    references[metadata["recording"]] = (table, metadata)
bias = read_json(snakemake.input.gyr).get("gyr_bias", {}).get("bias_ls_rad_s")
result = validate_references(
    {name: read_recording(snakemake.input[name])[0] for name in references},
    references,
    read_segments(snakemake.input.segments),
    read_json(snakemake.input.calibration),
    bias,
    {name: dataset.reference_where(name) for name in references},
    windows_s=snakemake.params.windows_s,
)
write_json(result, snakemake.output.validation)
save_figure(plot_orientation_errors(result), snakemake.output.figure)
