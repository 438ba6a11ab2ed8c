"""Rule blind_render: one blind session; the answer key goes to the sealed path only."""

import logging
from typing import TYPE_CHECKING

from imucal.gap.blind import render_blind_session
from imucal.io.logs import log_to

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
render_blind_session(snakemake.params.spec, snakemake.output.folder, snakemake.output.key)
logging.info("rendered %s", snakemake.wildcards.session)
