"""Rule blind_render: one blind session; the answer key goes to the sealed path only."""

import logging
from typing import TYPE_CHECKING

from imucal.gap.blind import render_blind_session

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
render_blind_session(snakemake.params.spec, snakemake.output.folder, snakemake.output.key)
logging.info("rendered %s", snakemake.wildcards.session)
