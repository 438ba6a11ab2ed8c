"""What a session's stages produced, for its files: the stage listing (``stages.json``) of the
stage-per-rule path; the calibration, the artifacts per sensor and the figures of the partial
path.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd

from imucal.calibration import FORMAT_VERSION
from imucal.columns import SENSORS
from imucal.pipeline.outcome import not_run_reason
from imucal.pipeline.partial.session import Outcome
from imucal.pipeline.registry import STAGES, VALIDATE


def full_protocol_stages(
    recordings: Mapping | set,
    *,
    has_reference: bool,
    artifacts: Mapping[str, Mapping] | None = None,
    notes: Mapping[str, str] | None = None,
) -> list[dict]:
    """The stage listing (``stages.json``) of a session run by the stage-per-rule workflow.

    Parameters
    ----------
    recordings : collection of str
        The dataset's recording names (it has rotation3d and cube with all sensors).
    has_reference : bool
    artifacts : mapping, optional
        Stage name (and 'validate') -> its artifact; a not-run record
        (:mod:`imucal.pipeline.outcome`) makes the stage 'skipped' with the reason the data gave.
    notes : mapping, optional
        Segmentation notes per recording; those of recordings whose protocol was not found
        join the reasons of the stages that did not run.

    Returns
    -------
    list of dict
        {stage, what, status, reason} per stage of :data:`STAGES` plus the validation.
    """

    skipped = {
        "acc_known_orientation": "not applicable: the cube fit and T_R,acc of the full protocol "
        "are used (no ferraris recording)",
        "gyr_known_rotation": "not applicable: no ferraris recording",
        "gyr_reference": "not applicable: the full protocol calibrates the gyroscope with the "
        "platform (an orientation reference is declared on partial sessions' recordings)",
        "acc_reference": "not applicable: the full protocol calibrates the accelerometer with "
        "the cube and the platform",
        "mag_reference": "not applicable: the full protocol aligns the magnetometer with the "
        "platform's phases (mag_step2)",
        "gyr_pose_to_pose": "not applicable: the full protocol calibrates the gyroscope with the "
        "platform (and rate table)",
    }
    if "ratetable" not in recordings:
        skipped["gyr_table"] = "not applicable: needs a ratetable recording"
    failed = [n for n in (notes or {}).values() if "automatic segmentation failed" in n]
    context = f" (segmentation: {'; '.join(failed)})" if failed else ""
    for name, artifact in (artifacts or {}).items():
        if not_run_reason(artifact):
            skipped[name] = f"could not run on these data: {artifact['not_run']['reason']}{context}"
    rows = [
        {
            "stage": name,
            "what": stage.what,
            "status": "skipped" if name in skipped else "run",
            "reason": skipped.get(name, stage.what),
        }
        for name, stage in STAGES.items()
    ]
    rows.append({
        "stage": VALIDATE.name, "what": VALIDATE.what,
        "status": "skipped" if "validate" in skipped else "run",
        "reason": skipped.get("validate") or ("against the reference" if has_reference
        else "reference-free checks only: the dataset has no reference recording"),
    })  # fmt: skip
    return rows


@dataclass(frozen=True)
class PartialFiles:
    """What a partial session's rule writes.

    Attributes
    ----------
    outcomes : list of Outcome
        Each stage's, in the registry's order.
    calibration : dict
        ``calibration.json`` (:func:`calibration_file`).
    stages : dict
        ``stages.json``: the dataset's name and each stage's summary.
    artifacts : dict
        Sensor -> the artifacts of its stages that ran (``{mag,acc,gyr}.json``).
    """

    outcomes: list[Outcome]
    calibration: dict
    stages: dict
    artifacts: dict


def calibration_file(final: Mapping) -> dict:
    """``calibration.json`` of a partial session from its final calibration
    (:func:`imucal.pipeline.partial.final_calibration`): the format version, each sensor's
    calibration that ran, why the others have none, and the frame they are in."""
    return {
        "format_version": FORMAT_VERSION,
        **{sensor: entry["calibration"] for sensor, entry in final["sensors"].items()},
        "missing": final["missing"],
        "frame": "B of the session's own protocol (see each sensor's method)",
    }


def stage_results(outcomes: list[Outcome]) -> dict[str, dict]:
    """Per sensor, the artifacts of its stages that ran (the report's stage results)."""
    out: dict[str, dict] = {s: {} for s in SENSORS}
    for o in outcomes:
        if o.status == "run":
            out[o.name.split("_", 1)[0]][o.name] = o.artifact
    return out


def figures(outcomes: list[Outcome], tables: Mapping[str, pd.DataFrame]) -> dict:
    """Figures of the stages that ran (file stem -> matplotlib Figure).

    ``mag_raw`` / ``mag_step1`` (the ellipsoid fit's samples before and after), ``acc_cube`` or
    ``acc_known_orientation`` (|a| - g per pose before and after), ``gyr_pose_to_pose``
    (gravity-direction error per interval before and after).
    """
    from imucal.fits import magnetometer
    from imucal.plots import inertial as plots
    from imucal.plots.magnetometer import plot_field

    done = {o.name: o.artifact for o in outcomes if o.status == "run"}
    out = {}
    if "mag_step1" in done:
        fit = magnetometer.EllipsoidFit.from_dict(dict(done["mag_step1"]))
        t, raw = magnetometer.field_samples(tables[done["mag_step1"]["source"]])
        source = done["mag_step1"]["source"]
        out["mag_raw"] = plot_field(t, raw, f"Magnetometer, raw ({source})")
        out["mag_step1"] = plot_field(
            t,
            fit.apply(raw),
            f"After step 1, the ellipsoid fit ({fit.used}; {source})",
            fit.field_norm,
        )
    if "acc_cube" in done:
        a = done["acc_cube"]
        out["acc_cube"] = plots.plot_before_after_errors(
            a["labels"],
            a["magnitude_error_before_m_s2"],
            a["magnitude_error_after_m_s2"],
            "m/s^2",
            f"Accelerometer fit (eq. 32) on {a['recording']} (in-sample)",
            quantity="|a| - g",
        )
    if "acc_known_orientation" in done:
        a = done["acc_known_orientation"]
        raw_norm = np.linalg.norm(np.asarray(a["position_means"], dtype=float), axis=1)
        out["acc_known_orientation"] = plots.plot_before_after_errors(
            a["labels"],
            raw_norm - a["gravity_m_s2"],
            a["magnitude_error_m_s2"],
            "m/s^2",
            "Accelerometer from faces of known orientation (in-sample)",
            quantity="|a| - g",
        )
    if "gyr_pose_to_pose" in done:
        g = done["gyr_pose_to_pose"]
        n = len(g["angle_errors_deg"])
        out["gyr_pose_to_pose"] = plots.plot_before_after_errors(
            [f"{k + 1}" for k in range(n)],
            g["angle_errors_before_deg"],
            g["angle_errors_deg"],
            "deg",
            "Gyroscope pose to pose (in-sample; before: nominal scale)",
            quantity="gravity-direction error",
        )
    return out
