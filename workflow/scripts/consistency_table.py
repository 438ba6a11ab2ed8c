"""Rule consistency_table: the public recordings' checks of their standard deviations as one
Markdown table (imucal.report.consistency.markdown_table)."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.io import read_json
from imucal.report.consistency import markdown_table

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

logging.basicConfig(filename=snakemake.log[0], filemode="w", level=logging.INFO)
checks = {name: read_json(path) for name, path in snakemake.input.items()}
Path(snakemake.output.table).write_text(markdown_table(checks), encoding="utf-8")
