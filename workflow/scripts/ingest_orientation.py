"""Rule ingest_orientation: the orientation reference of one recording -> parquet (imucal.ingest)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.ingest import ingest_orientation_reference
from imucal.io import write_recording
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
try:
    table, metadata = ingest_orientation_reference(
        snakemake.wildcards.recording, dataset, imucal_version=snakemake.params.imucal_version
    )
except (ValueError, FileNotFoundError) as err:  # the data's fault: its message, no traceback
    logging.exception("reference of %s failed", snakemake.wildcards.recording)
    raise SystemExit(f"reference of {snakemake.wildcards.recording}: {err}") from None
write_recording(table, snakemake.output.table, metadata)
logging.info("%d rows, %d gap rows", len(table), metadata["gap_rows"])
