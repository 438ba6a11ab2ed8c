"""Rules blind_diagnose, stress_diagnose, detection_diagnose: ingest a check's session in
process and diagnose it without its answer key; a failure is recorded, not raised."""

import logging
from typing import TYPE_CHECKING

from imucal.gap import DiagnosisSettings
from imucal.gap.checks import diagnose_folder
from imucal.io import write_json
from imucal.io.logs import log_to

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
p = snakemake.params
session = snakemake.wildcards.session
result = diagnose_folder(
    snakemake.input.folder,
    session,
    imucal_version=p.imucal_version,
    settings=DiagnosisSettings.from_config(p.settings),
    pipeline=p.pipeline,
)
if result.get("failed"):
    logging.getLogger(__name__).error(
        "%s failed in the %s:\n%s", session, result["failed_in"], "".join(result["traceback"])
    )
write_json(result, snakemake.output.diagnosis)
