"""Every stage rule of the paper's protocol: reads the node's inputs, runs it
(imucal.pipeline.graph), writes its artifact and figures, or their not-run forms when the data
do not allow the stage."""

from typing import TYPE_CHECKING

from imucal.io import write_json
from imucal.io.logs import log_to
from imucal.pipeline.graph import FULL_PROTOCOL, node_inputs, read_source, write_output
from imucal.pipeline.outcome import stage_guard

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
node = FULL_PROTOCOL[snakemake.rule]
recordings = frozenset(snakemake.params.recordings)
sources = node.reads(recordings)

with stage_guard(node.name, snakemake.output):
    store = {sources[arg]: read_source(sources[arg], path) for arg, path in snakemake.input.items()}
    artifact, outputs = node.run(
        node_inputs(node, store, recordings), snakemake.params.settings, True
    )
    write_json(artifact, snakemake.output.artifact)
    for key, value in outputs.items():
        write_output(value, snakemake.output[key])
