"""Rule export: the calibration and its noise as Kalibr, OpenVINS and ROS files."""

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imucal.export import FORMATS, export_files
from imucal.io.logs import log_to
from imucal.pipeline.outcome import read_artifact, stage_guard

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])
logger = logging.getLogger("export")
folder = Path(snakemake.output.ros).parent.parent  # results/{dataset}/export/{format}/

with stage_guard("export", snakemake.output):
    calibration = read_artifact(snakemake.input.calibration)
    noise = read_artifact(snakemake.input.noise)
    for fmt in FORMATS:
        for name, text in export_files(fmt, calibration, noise).items():
            (folder / fmt / name).write_text(text, encoding="utf-8")
            logger.info("wrote %s", folder / fmt / name)
