"""Simulated hand-held and robot sessions with an orientation reference and a magnetometer,
clean or with one disturbance (``world_magnetic``, ``shock``, ``vibration``), ready for the
partial-session diagnosis; shared by tests/gap/test_gap_disturbance.py and
tests/benchmarks/gap/bench_disturbances.py."""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.calibration import SensorCalibration
from imucal.columns import ACC, GYR, MAG, POSITION, QUAT, SEGMENT_COLUMNS, TIME
from imucal.gap import DiagnosisSettings
from imucal.gap.composite import diagnose_partial_session
from imucal.gap.motion import motion_part
from imucal.orientation import interpolate_orientation
from imucal.sim.effects import make_effect
from imucal.sim.orientation import simulate_orientation_session

MATRIX = errormodel.compose([1.02, 0.98, 1.01], [0.004, -0.003, 0.005], [0.0, 0.0, 0.0])
BIAS = np.array([0.01, -0.02, 0.015])
MAG_MATRIX = errormodel.compose([1.05, 0.97, 1.02], [0.01, -0.02, 0.015], [0.0, 0.0, 0.0])
MAG_BIAS = np.array([0.2, -0.1, 0.3])
MOUNTING = Rotation.from_rotvec([0.3, -0.2, 0.8]).as_matrix()
#: Magnetometer noise, normalised field: 0.6 uT of 48 uT (AK8963 class, effects.md #7).
MAG_NOISE = 0.0125
#: Accelerometer noise, m/s^2 (a MEMS of 400 ug/sqrt(Hz) at 100 Hz bandwidth).
ACC_NOISE = 0.04
#: The protocols: a hand under optical motion capture (120 Hz, 0.5 mrad, tracking gaps) and a
#: robot arm reporting its flange's orientation from its encoders (100 Hz, 0.1 mrad, no gaps).
PROTOCOLS = {
    "hand": {"moves": "hand", "reference_rate_hz": 120.0, "orientation_noise_rad": 5e-4},
    "robot": {
        "moves": "robot",
        "reference_rate_hz": 100.0,
        "orientation_noise_rad": 1e-4,
        "gaps": 0,
    },
}
SETTINGS = DiagnosisSettings(replicas=12, seed=0, crn_seeds=3)
#: The module 0.15 m from the wrist or the flange (body frame, m): with a position track the
#: reference reports where it is (``position=True``).
ARM_M = np.array([0.1, 0.05, 0.1])
#: A magnet fixed in the world near the path (``world_dipole``): a small NdFeB disc (0.24 A m^2,
#: 5.5e-4 Earth fields m^3 against 44 uT) 0.3 m from the pivot, so 0.15-0.45 m from the
#: module: 0.16 Earth fields at the nearest, 0.006 at the farthest; no uniform gradient.
WORLD_DIPOLE = {
    "grad_xx": 0.0, "grad_yy": 0.0, "grad_xy": 0.0, "grad_xz": 0.0, "grad_yz": 0.0,
    "dipole_x_m": 0.3, "dipole_y_m": 0.0, "dipole_z_m": 0.0,
    "moment_x": 3.2e-4, "moment_y": -3.2e-4, "moment_z": 3.2e-4,
}  # fmt: skip


#: What the disturbances must not be taken for: the reference's samples off their time stamps
#: by 0.3 ms RMS (``reference_jitter``, which the library has), a magnetometer 30 ms late
#: (``mag_delay``: the field at each packet is the one 30 ms before; the library has no lag)
#: and glitches of an optical reference (``reference_glitches``: 2 % of its samples 3 ms off
#: their stamps, either way; the residual against the gyroscope has heavy tails at fast motion
#: and the accelerometer has no spike).
CONFOUNDERS = {"reference_jitter": 3e-4, "mag_delay": 0.03, "reference_glitches": 3e-3}
#: Share of the reference's samples a glitch takes off its stamp.
GLITCH_FRACTION = 0.02


def glitched(t_reference: np.ndarray, quat: np.ndarray, offset_s: float, seed: int) -> np.ndarray:
    """The reference with :data:`GLITCH_FRACTION` of its samples (those with present
    neighbours) replaced by the orientation ``offset_s`` before or after their stamp."""
    rng = np.random.default_rng([seed, 7])
    present = np.all(np.isfinite(quat), axis=1)
    inner = np.flatnonzero(present[1:-1] & present[:-2] & present[2:]) + 1
    picked = rng.choice(inner, size=int(GLITCH_FRACTION * len(inner)), replace=False)
    tau = t_reference[picked] + offset_s * rng.choice([-1.0, 1.0], size=len(picked))
    out = quat.copy()
    out[picked] = interpolate_orientation(t_reference[present], quat[present], tau)
    return out


def case_inputs(
    protocol: str, effect: str | None, seed: int, duration_s: float = 120.0, position=False
):
    """The simulated session, its calibration and its motion part
    (:func:`imucal.gap.motion.motion_part`); ``effect`` a simulator effect at its realistic
    size, a confounder (:data:`CONFOUNDERS`), ``world_dipole`` (:data:`WORLD_DIPOLE`) or None.
    ``position``: the module at :data:`ARM_M` from the pivot, the reference with its position
    (``world_dipole`` has it always)."""
    position = position or effect == "world_dipole"
    if effect == "world_dipole":
        effects = (make_effect("world_magnetic", **WORLD_DIPOLE),)
    else:
        effects = (make_effect(effect),) if effect and effect not in CONFOUNDERS else ()
    jitter = CONFOUNDERS["reference_jitter"] if effect == "reference_jitter" else 0.0
    s = simulate_orientation_session(
        seed, matrix=MATRIX, bias=BIAS, mounting=MOUNTING, offset_s=0.3, duration_s=duration_s,
        mag_matrix=MAG_MATRIX, mag_bias=MAG_BIAS, mag_noise=MAG_NOISE, effects=effects,
        acc_noise_m_s2=ACC_NOISE,
        reference_jitter_s=jitter, arm_m=ARM_M if position else None, **PROTOCOLS[protocol],
    )  # fmt: skip
    mag = s.mag
    if effect == "mag_delay":
        late = s.t_module - CONFOUNDERS["mag_delay"]
        mag = np.column_stack([np.interp(late, s.t_module, s.mag[:, k]) for k in range(3)])
    table = pd.DataFrame({
        TIME: s.t_module, **dict(zip(ACC, s.acc.T)), **dict(zip(GYR, s.gyr.T)),
        **dict(zip(MAG, mag.T)),
    })  # fmt: skip
    quat = s.quat_reference
    if effect == "reference_glitches":
        quat = glitched(s.t_reference, quat, CONFOUNDERS[effect], seed)
    reference = pd.DataFrame({TIME: s.t_reference, **dict(zip(QUAT, quat.T))})
    if position:
        reference[list(POSITION)] = s.pos_reference
    rests = [
        {"recording": "moves", "label": f"s{k + 1:02d}", "kind": "static", "start_s": lo,
         "end_s": hi, "start_index": 0, "end_index": 0, "axis": "", "rate_dps": np.nan,
         "sense": 0, "turns": np.nan, "up": "", "angle_deg": np.nan}
        for k, (lo, hi) in enumerate(s.rests_s)
    ]  # fmt: skip
    calibration = {
        "gyr": SensorCalibration("gyr", BIAS, MATRIX, "rad/s").to_dict(),
        "mag": SensorCalibration("mag", MAG_BIAS, MAG_MATRIX, "normalised").to_dict(),
    }
    motion = motion_part(
        {"moves": table},
        {"moves": (reference, {"up": "+z"})},
        calibration,
        pd.DataFrame(rests, columns=list(SEGMENT_COLUMNS)),
        {"moves": "d.yaml: recordings.moves.reference"},
        {},
        9.81,
        (1.0, 10.0),
    )
    return s, calibration, motion


def diagnose_case(
    protocol: str, effect: str | None, seed: int, settings=SETTINGS, position=False
) -> dict:
    """diagnosis.json of one simulated session (``position`` as in :func:`case_inputs`)."""
    _, calibration, motion = case_inputs(protocol, effect, seed, position=position)
    return diagnose_partial_session(
        None, motion=motion, dataset="sim", calibration=calibration, sensitivity={},
        gravity_m_s2=9.81, settings=settings,
    )  # fmt: skip
