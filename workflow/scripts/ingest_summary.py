"""Rule ingest_summary: all ingested recordings of a dataset -> summary.json (imucal.ingest)."""

import logging
from typing import TYPE_CHECKING

from imucal.ingest import summarize_dataset
from imucal.io import read_recording, write_json
from imucal.io.logs import log_to

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
log = logging.getLogger(__name__)
try:
    recordings = {name: read_recording(path) for name, path in snakemake.input.items()}
    summary = summarize_dataset(recordings, dataset=snakemake.wildcards.dataset)
    write_json(summary, snakemake.output.summary)
    log.info("%d recordings, %d lost packets", len(recordings), summary["lost_packets"])
except Exception:
    log.exception("ingest summary of %s failed", snakemake.wildcards.dataset)
    raise
