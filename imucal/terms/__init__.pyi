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
from .registry import (
    declaration_problems,
    register,
    registered_terms,
    term_class,
    term_names,
    unregister,
)
from .selection import EFFECT_OF_TERM, TermSettings, decide, final_calibration
from .term import ModelTerm, ReportRow, Samples, ValueTerm
