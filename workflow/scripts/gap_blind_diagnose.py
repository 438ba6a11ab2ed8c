"""Rule blind_diagnose: ingest a blind session in process and diagnose it (no answer key)."""

import logging
from typing import TYPE_CHECKING

from imucal.constants import IMU_RECORDINGS
from imucal.gap import diagnose
from imucal.gap.blind import failed_diagnosis
from imucal.ingest import ingest_recording
from imucal.io import write_json
from imucal.io.dataset import read_dataset
from imucal.pipeline.full import PipelineOptions

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
p = snakemake.params
info = read_dataset(snakemake.input.folder)
tables = {
    r: ingest_recording(path, r, info, p.imucal_version)[0] for r, path in info.recordings.items()
}
imu = {r: t for r, t in tables.items() if r in IMU_RECORDINGS}
options = PipelineOptions.of_dataset(
    info,
    exact_rotation=p.exact_rotation,
    lowpass_order=p.lowpass_order,
    lowpass_cutoff_hz=p.lowpass_cutoff_hz,
)
try:
    result = diagnose(
        imu, tables.get("reference"), options, dataset=snakemake.wildcards.session,
        replicas=p.replicas, alpha=p.alpha, seed=p.seed,
        min_heldout_shrink=p.min_heldout_shrink, crn_seeds=p.crn_seeds, detect_z=p.detect_z,
        exclude=tuple(p.exclude),
    )  # fmt: skip
except ValueError as err:
    # the pipeline refused the session (e.g. segmentation of a clipped rate table): in the
    # blind check that is an outcome to score (a miss), not a reason to lose the other sessions
    logging.exception("the pipeline refused %s", snakemake.wildcards.session)
    result = failed_diagnosis(snakemake.wildcards.session, str(err))
write_json(result, snakemake.output.diagnosis)
