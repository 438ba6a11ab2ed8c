"""The session's own chain run again on independent parts of its data, for the check of its
standard deviations (:mod:`imucal.validation.consistency`): the partial path's stages
(:func:`check_partial_session`) or the paper's chain (:func:`check_full_session`), each with the
settings of the whole session, and what the stages left out one pose at a time themselves.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from scipy import special  # F and normal tails without scipy.stats' import

from imucal.calibration import SensorCalibration
from imucal.pipeline.full import calibrate_session
from imucal.pipeline.graph import usable
from imucal.pipeline.options import PipelineOptions
from imucal.pipeline.partial import Session, final_calibration, run_stages
from imucal.pipeline.registry import FINAL
from imucal.validation.consistency import PartFit, check_parts


def left_out(stage: str, artifact: Mapping | None) -> dict:
    """What a stage found by leaving its poses out one at a time: the held-out poses' z
    against their predicted std (``leave_one_out``) and their errors against the nominal
    calibration's (``heldout``); empty for a stage without it.

    The cube fit (``acc_cube``): ``|a| - g`` of each pose under the fit on the others, over the
    std its covariance and the pose's noise predict. The faces of known orientation
    (``acc_known_orientation``): each face's ``z2`` under the fit on the others, whose tail
    probability under ``3 F(3, dof)`` is given as the |z| of a standard normal with the same
    two-sided tail (so that the RMS z is about 1 when the model holds).
    """
    if not artifact:
        return {}
    if stage == "acc_cube" and "heldout_error_after_m_s2" in artifact:
        after = np.asarray(artifact["heldout_error_after_m_s2"], dtype=float)
        before = np.asarray(artifact["heldout_error_before_m_s2"], dtype=float)
        std = np.asarray(artifact["heldout_predicted_std_m_s2"], dtype=float)
        keep = np.isfinite(after) & np.isfinite(std) & (std > 0)
        if not keep.any():
            return {}
        basis = f"each of {int(keep.sum())} poses against the cube fit on the others"
        rms_after = float(np.sqrt(np.mean(after[keep] ** 2)))
        rms_before = float(np.sqrt(np.mean(before[keep] ** 2)))
        z = after[keep] / std[keep]
        return {
            "leave_one_out": {
                "rms_z": float(np.sqrt(np.mean(z**2))),
                "max_abs_z": float(np.abs(z).max()),
                "n": int(keep.sum()),
                "basis": basis,
            },
            "heldout": {
                "calibrated": rms_after,
                "nominal": rms_before,
                "ratio": rms_after / rms_before if rms_before else None,
                "basis": basis,
            },
        }
    if stage == "acc_known_orientation" and artifact.get("heldout_z2"):
        z2 = np.asarray(artifact["heldout_z2"], dtype=float)
        z2 = z2[np.isfinite(z2)]
        # each held-out fit estimates its placement tilt from its own residuals, with 3 dof
        # fewer than the whole fit's: z2 / 3 is F(3, dof) when the model holds, a heavy tail
        # for few faces; each face's tail probability as the |z| of a normal with the same one
        dof = int(artifact["dof"]) - 3
        if not z2.size or dof < 1:
            return {}
        p = special.fdtrc(3, dof, z2 / 3)
        z = special.ndtri(1 - p / 2)
        return {
            "leave_one_out": {
                "rms_z": float(np.sqrt(np.mean(z**2))),
                "max_abs_z": float(z.max()),
                "n": int(z2.size),
                "basis": f"each of {z2.size} faces against the fit on the others, z2 / 3 "
                f"against F(3, {dof})",
            }
        }
    return {}


def shipped_stages(listing: Sequence[Mapping]) -> dict[str, str]:
    """Per sensor the stage whose calibration a partial session ships: the first of its
    :data:`~imucal.pipeline.registry.FINAL` stages that ran (as ``final_calibration`` chooses)."""
    ran = {row["stage"] for row in listing if row["status"] == "run"}
    return {
        sensor: next(s for s in stages if s in ran)
        for sensor, stages in FINAL.items()
        if any(s in ran for s in stages)
    }


def fitted_recordings(artifacts: Mapping[str, Mapping | None]) -> dict[str, list[str]]:
    """Per sensor the recordings its stages fitted, as their artifacts name them: the
    accelerometer's poses (``recording`` of the cube fit or the known orientations), the
    gyroscope bias's rests (``source``), the ellipsoid's samples (``source`` and ``offered``)."""
    out = {}
    if (artifacts.get("acc_cube") or {}).get("recording"):
        out["acc"] = [artifacts["acc_cube"]["recording"]]
    elif artifacts.get("acc_known_orientation"):
        out["acc"] = ["ferraris"]
    if (artifacts.get("gyr_bias") or {}).get("source"):
        out["gyr"] = list(artifacts["gyr_bias"]["source"])
    step1 = artifacts.get("mag_step1") or {}
    if step1.get("source"):
        out["mag"] = [step1["source"], *step1.get("offered", [])]
    return out


def check_partial_session(
    session: Session,
    listing: Sequence[Mapping],
    calibration: Mapping,
    artifacts: Mapping[str, Mapping],
) -> dict:
    """The partial path's calibration checked on two independent parts of the session.

    Parameters
    ----------
    session : Session
        The session's recordings, segments, options and references, as its calibration ran
        (:func:`imucal.pipeline.partial.session_of`); each part runs with the same.
    listing : sequence of mapping
        ``partial/stages.json``'s ``stages``.
    calibration : mapping
        ``partial/calibration.json``.
    artifacts : mapping
        Stage -> artifact of the stages that ran (``partial/{mag,acc,gyr}.json`` together):
        the stages' own held-out errors and the recordings they fitted.

    Returns
    -------
    dict
        :func:`imucal.validation.consistency.check_parts`'s artifact.
    """
    ran = [row["stage"] for row in listing if row["status"] == "run"]

    def calibrate(part_tables, part_segments) -> dict[str, PartFit]:
        outcomes = run_stages(session.on(part_tables, part_segments), stages=ran)
        final = final_calibration(outcomes, session.options)
        return {
            sensor: PartFit(e["stage"], SensorCalibration.from_dict(sensor, e["calibration"]))
            for sensor, e in final["sensors"].items()
        }

    shipped = {
        sensor: PartFit(stage, SensorCalibration.from_dict(sensor, calibration[sensor]))
        for sensor, stage in shipped_stages(listing).items()
    }
    acc = shipped.get("acc")
    own = {"acc": left_out(acc.stage, artifacts.get(acc.stage))} if acc else {}
    return check_parts(
        calibrate,
        session.recordings,
        session.segments,
        shipped,
        gravity_m_s2=session.options.gravity_m_s2,
        field_norm=session.options.field_norm,
        own=own,
        sources=fitted_recordings(artifacts),
    )


def _full_fits(tables, segments, options: PipelineOptions) -> tuple[dict[str, PartFit], dict]:
    """The paper's chain on (part of) a session: per sensor its final stage and calibration
    (none when the chain stops), and the stages' artifacts."""
    try:
        fit = calibrate_session(tables, None, options, segments)
    except ValueError:  # a part that does not allow a sensor's final stage ships nothing
        return {}, {}
    gyr = "gyr_table" if usable(fit.artifacts.get("gyr_table")) else "gyr_scale"
    stages = {"acc": "acc_align", "gyr": gyr, "mag": "mag_step2"}
    return {s: PartFit(stage, fit.calibration.sensor(s)) for s, stage in stages.items()}, (
        fit.artifacts
    )


def check_full_session(
    tables: Mapping[str, pd.DataFrame], segments: pd.DataFrame, options: PipelineOptions
) -> dict:
    """The paper's calibration checked on two independent parts of the session (the chain of
    :func:`imucal.pipeline.full.calibrate_session` on each, with the session's options).

    Returns
    -------
    dict
        :func:`imucal.validation.consistency.check_parts`'s artifact.
    """
    shipped, artifacts = _full_fits(tables, segments, options)
    return check_parts(
        lambda t, s: _full_fits(t, s, options)[0],
        tables,
        segments,
        shipped,
        gravity_m_s2=options.gravity_m_s2,
        field_norm=options.field_norm,
        own={"acc": left_out("acc_cube", artifacts.get("acc_cube"))},
        sources=fitted_recordings(artifacts),
    )
