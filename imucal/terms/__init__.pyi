from .estimators import estimator_of, register_estimator, unregister_estimator
from .gsensitivity import fit_g_sensitivity
from .leverarm import fit_lever_arm
from .loop import (
    close_loop,
    corrected_session,
    diagnosis_after,
    terms_summary,
)
from .magdelay import fit_mag_delay
from .poseholdout import hold_out_poses, hold_out_recording
from .selection import TermSettings, decide, final_calibration
