"""Rule stages_full: the stage listing of a session run by the stage-per-rule workflow, from the
artifacts of the stages (run, or the reason they did not)."""

from pathlib import Path
from typing import TYPE_CHECKING

from imucal.io import read_json, read_recording, write_json
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.pipeline.partial import full_protocol_stages
from imucal.pipeline.registry import full_protocol_artifacts

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
stage_names = full_protocol_artifacts()
artifacts = {
    stage: read_json(path) for stage, path in snakemake.input.items() if stage in stage_names
}
stages = full_protocol_stages(
    set(dataset.recordings),
    has_reference=dataset.has("reference"),
    artifacts=artifacts,
    notes=read_recording(snakemake.input.segments)[1].get("notes", {}),
)
write_json({"dataset": dataset.name, "stages": stages}, snakemake.output.stages)
