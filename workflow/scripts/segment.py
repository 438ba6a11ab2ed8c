"""Rule segment: ingested IMU recordings of a dataset -> segments table (imucal.segments.segmentation)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.io import read_recording, write_recording
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.segments.segmentation import segment_dataset

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake

log_to(snakemake.log[0])
try:
    dataset = read_dataset(Path(snakemake.input.dataset_yaml).parent)
    names = [name for name in dataset.recordings if name != "reference"]
    loaded = {name: read_recording(getattr(snakemake.input, name)) for name in names}
    tables = {name: table for name, (table, _) in loaded.items()}
    # a section list of dataset.yaml was resolved at ingest (metadata 'sections')
    sections = [
        {"recording": name, **entry}
        for name, (_, meta) in loaded.items()
        for entry in meta.get("sections", [])
    ]
    p = snakemake.params
    segments = segment_dataset(
        tables,
        ratetable=dataset.ratetable,
        manual=dataset.segments + sections,
        **p.settings,
        fallback=True,
    )
    write_recording(
        segments,
        snakemake.output.segments,
        {
            "dataset": dataset.name,
            "imucal_version": p.imucal_version,
            "notes": segments.attrs.get("notes", {}),
            "held_by_hand": segments.attrs.get("held_by_hand", []),
        },
    )
    logging.info(
        "%d segments -> %s\n%s", len(segments), snakemake.output.segments, segments.to_string()
    )
except Exception:
    logging.exception("segmentation of %s failed", snakemake.wildcards.dataset)
    raise
