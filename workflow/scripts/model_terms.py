"""Rule model_terms: the closed loop's terms (terms.json) and the diagnosis after it."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.constants import IMU_RECORDINGS
from imucal.gap import DiagnosisSettings
from imucal.io import read_json, read_recording, read_segments, write_json
from imucal.io.dataset import read_dataset
from imucal.io.logs import log_to
from imucal.pipeline.full import PipelineOptions
from imucal.terms import TermSettings, close_loop, diagnosis_after, terms_summary

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
p = snakemake.params
recordings = dict(snakemake.input.items())
imu = {r: read_recording(recordings[r])[0] for r in IMU_RECORDINGS if r in recordings}
reference = read_recording(recordings["reference"])[0] if "reference" in recordings else None
options = PipelineOptions.of_dataset(
    read_dataset(Path(snakemake.input.dataset_yaml).parent), **p.pipeline
)
segments = read_segments(snakemake.input.segments)
result = close_loop(
    imu,
    reference,
    options,
    segments=segments,
    diagnosis=read_json(recordings["diagnosis"]) if recordings.get("diagnosis") else None,
    settings=TermSettings.from_config(p.terms),
    fits={
        k.removeprefix("fit_"): read_json(v) for k, v in recordings.items() if k.startswith("fit_")
    },
)
after = diagnosis_after(
    result,
    reference,
    options,
    dataset=snakemake.wildcards.dataset,
    segments=segments,
    settings=DiagnosisSettings.from_config(p.settings),
)
write_json(terms_summary(result), snakemake.output.terms)
write_json(after, snakemake.output.after)
logging.info("terms in the model: %s", terms_summary(result)["in_model"])
