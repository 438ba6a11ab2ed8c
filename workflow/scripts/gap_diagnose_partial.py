"""Rule gap_diagnose_partial: the gap diagnosis of a partial session (imucal.gap.static)."""

import logging
from typing import TYPE_CHECKING

from imucal.gap.figures import plot_effects, plot_gap_map
from imucal.gap.static import diagnose_partial_session
from imucal.io import read_json, read_recording, write_json
from imucal.io.dataset import read_dataset

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
p = snakemake.params
info = read_dataset(p.folder)
static = read_recording(snakemake.input.static)[0] if "static" in snakemake.input.keys() else None  # noqa: SIM118
result = diagnose_partial_session(
    static, dataset=snakemake.wildcards.dataset, calibration=read_json(snakemake.input.calibration),
    sensitivity=info.sensitivity, gravity_m_s2=info.gravity_m_s2, replicas=p.replicas,
    alpha=p.alpha, seed=p.seed, min_heldout_shrink=p.min_heldout_shrink, crn_seeds=p.crn_seeds,
    detect_z=p.detect_z,
)  # fmt: skip
write_json(result, snakemake.output.diagnosis)
plot_gap_map(result).savefig(snakemake.output.gap_map, dpi=110)
plot_effects(result).savefig(snakemake.output.effects, dpi=110)
logging.info("scope %s, explained %s", result["scope"], result["explained"])
