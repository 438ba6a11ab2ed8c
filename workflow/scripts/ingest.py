"""Rule ingest: one raw or declared recording -> checked parquet in SI units (imucal.ingest)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.ingest import ingest_recording
from imucal.io import write_recording
from imucal.io.dataset import read_dataset

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
log = logging.getLogger(__name__)
try:
    dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
    raw = dataset.recordings[snakemake.wildcards.recording]  # the others: snakemake.input.raw
    table, metadata = ingest_recording(
        raw,
        recording=snakemake.wildcards.recording,
        dataset=dataset,
        imucal_version=snakemake.params.imucal_version,
    )
    write_recording(table, snakemake.output.table, metadata)
    log.info("%s: %d rows -> %s", list(snakemake.input.raw), len(table), snakemake.output.table)
except Exception:
    log.exception("ingest of %s failed", snakemake.input.raw)
    raise
