"""Rule stress_diagnose: diagnose a stress session (a failure is recorded, not raised)."""

import logging
from typing import TYPE_CHECKING

from imucal.gap.stress import diagnose_folder
from imucal.io import write_json

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
p = snakemake.params
result = diagnose_folder(
    snakemake.input.folder, snakemake.wildcards.session, imucal_version=p.imucal_version,
    replicas=p.replicas, alpha=p.alpha, seed=p.seed, min_heldout_shrink=p.min_heldout_shrink,
    crn_seeds=p.crn_seeds, detect_z=p.detect_z,
)  # fmt: skip
if result.get("failed"):
    logging.getLogger(__name__).error(
        "%s failed in the %s:\n%s", snakemake.wildcards.session, result["failed_in"],
        "".join(result["traceback"]),
    )  # fmt: skip
write_json(result, snakemake.output.diagnosis)
