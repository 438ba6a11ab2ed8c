"""The stages of the workflow, as functions of their input tables: one function per rule of the
paper's stage-per-rule path.

Each function is what one rule runs: it cuts the segments it needs out of the ingested (or
low-pass filtered) tables, calls the fits of :mod:`imucal.fits` and returns a JSON-ready artifact
(and figures, never saved here). Stages exchange their results through these artifacts, so one
stage can be rerun on new data. The in-process chain (:mod:`imucal.pipeline.full`) and the partial
path (:mod:`imucal.pipeline.partial`) call the same functions, so a stage is written once.

The functions live in one module per sensor or role and are re-exported here:
:mod:`.accelerometer` (cube fit, alignment, the cube's calibration and quality),
:mod:`.gyroscope` (bias, alignment, rate table), :mod:`.toolfree` (the scale without tools,
eq. 36), :mod:`.magnetometer` (steps 1 and 2), :mod:`.calibration` (the gyroscope's and the
whole calibration, its application, the validation and their figures) and :mod:`.common` (what
they share).
"""

from imucal.pipeline.stages.accelerometer import (
    align_acc,
    cube_calibration,
    cube_quality,
    fit_acc_cube,
)
from imucal.pipeline.stages.calibration import (
    PAPER_TABLE_I,
    PAPER_TABLE_II,
    apply_calibration,
    calibration_of_what_ran,
    combine_calibration,
    combine_gyr,
    plot_phases,
    plot_validation,
    validate_session,
)
from imucal.pipeline.stages.common import ALIGNMENT_METHODS, plain
from imucal.pipeline.stages.gyroscope import (
    RATE_TABLE_RULE,
    align_gyr,
    estimate_gyr_bias,
    fit_gyr_table,
    gyr_bias_quality,
    gyr_bias_value,
)
from imucal.pipeline.stages.magnetometer import align_mag, fit_mag_step1
from imucal.pipeline.stages.toolfree import (
    TOOL_FREE_RULE,
    estimate_gyr_scale,
    integration_times,
    tool_free_gyr,
)

__all__ = [
    "ALIGNMENT_METHODS",
    "PAPER_TABLE_I",
    "PAPER_TABLE_II",
    "RATE_TABLE_RULE",
    "TOOL_FREE_RULE",
    "align_acc",
    "align_gyr",
    "align_mag",
    "apply_calibration",
    "calibration_of_what_ran",
    "combine_calibration",
    "combine_gyr",
    "cube_calibration",
    "cube_quality",
    "estimate_gyr_bias",
    "estimate_gyr_scale",
    "fit_acc_cube",
    "fit_gyr_table",
    "fit_mag_step1",
    "gyr_bias_quality",
    "gyr_bias_value",
    "integration_times",
    "plain",
    "plot_phases",
    "plot_validation",
    "tool_free_gyr",
    "validate_session",
]
