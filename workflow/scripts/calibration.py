"""Rule calibration: calibration.json of the three sensors in frame B (with the reason for a
sensor whose stages did not run), or the closed loop's recalibration with its model terms; the
standard deviations inflated where independent parts of the data disagree beyond them."""

from typing import TYPE_CHECKING

from imucal.io import read_json, write_json
from imucal.io.logs import log_to
from imucal.pipeline.stages import calibration_of_what_ran
from imucal.terms import final_calibration
from imucal.validation.consistency import ship

if TYPE_CHECKING:
    from snakemake.iocontainers import snakemake  # noqa: TC004 (Snakemake injects it)

log_to(snakemake.log[0])

artifacts = {sensor: read_json(snakemake.input[sensor]) for sensor in ("acc", "gyr", "mag")}
paper = calibration_of_what_ran(artifacts)
calibration = final_calibration(paper, read_json(snakemake.input.terms))
write_json(ship(calibration, read_json(snakemake.input.check)), snakemake.output.calibration)
