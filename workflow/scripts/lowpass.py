"""Rule lowpass: ingested recording -> zero-phase low-pass per contiguous block (imucal.segments.filtering)."""

import logging
from typing import TYPE_CHECKING

from imucal.io import read_recording, write_recording
from imucal.io.logs import log_to
from imucal.segments.filtering import lowpass_recording

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake

log_to(snakemake.log[0])
try:
    table, metadata = read_recording(snakemake.input.table)
    filtered = lowpass_recording(
        table, order=snakemake.params.order, cutoff_hz=snakemake.params.cutoff_hz
    )
    write_recording(
        filtered, snakemake.output.table, {**metadata, "lowpass": filtered.attrs["lowpass"]}
    )
    logging.info(
        "%s -> %s: %s", snakemake.input.table, snakemake.output.table, filtered.attrs["lowpass"]
    )
except Exception:
    logging.exception("lowpass of %s failed", snakemake.input.table)
    raise
