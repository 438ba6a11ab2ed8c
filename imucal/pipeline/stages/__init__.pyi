from .accelerometer import (
    align_acc,
    cube_calibration,
    cube_quality,
    fit_acc_cube,
)
from .calibration import (
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
from .common import ALIGNMENT_METHODS, at_range, plain
from .gyroscope import (
    RATE_TABLE_RULE,
    align_gyr,
    estimate_gyr_bias,
    fit_gyr_table,
    gyr_bias_quality,
    gyr_bias_value,
)
from .magnetometer import align_mag, fit_mag_step1
from .toolfree import (
    TOOL_FREE_RULE,
    estimate_gyr_scale,
    integration_times,
    tool_free_gyr,
)
