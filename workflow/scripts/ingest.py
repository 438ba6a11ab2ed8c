"""Rule ingest: one raw or declared recording -> checked parquet in SI units (imucal.ingest;
a native CSV is streamed in batches)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.ingest import ingest_to_parquet
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
log = logging.getLogger(__name__)
try:
    dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
    raw = dataset.recordings[snakemake.wildcards.recording]  # the others: snakemake.input.raw
    metadata = ingest_to_parquet(
        raw,
        recording=snakemake.wildcards.recording,
        dataset=dataset,
        imucal_version=snakemake.params.imucal_version,
        out=snakemake.output.table,
    )
    log.info(
        "%s -> %s (sha256 %s)",
        list(snakemake.input.raw),
        snakemake.output.table,
        metadata["sha256"],
    )
except (ValueError, FileNotFoundError) as err:  # the data's fault: its message, no traceback
    log.exception("ingest of %s failed", snakemake.input.raw)
    raise SystemExit(f"ingest of {snakemake.wildcards.recording}: {err}") from None
except Exception:
    log.exception("ingest of %s failed", snakemake.input.raw)
    raise
