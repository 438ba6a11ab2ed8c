"""The simulated checks of the diagnosis (blind, stress, detection): one way to score a run.

Each check renders sessions with sealed answer keys (:func:`imucal.gap.blind.render_blind_session`),
diagnoses them without the keys (:func:`diagnose_folder`: ingest, calibrate and diagnose, a
failure recorded rather than raised), and is scored by its own function once every diagnosis is
done; :func:`score_check` unseals the keys, scores, adds the diagnosis run times and renders the
check's page.
"""

from __future__ import annotations

import traceback
from collections.abc import Mapping, Sequence
from pathlib import Path

from imucal.constants import IMU_RECORDINGS
from imucal.gap.blind import blind_plan, failed_diagnosis, score_blind
from imucal.gap.detection import detection_plan, score_detection
from imucal.gap.diagnosis import diagnose
from imucal.gap.figures import render_blind_page, render_detection_page
from imucal.gap.outside import outside_plan, render_outside_page, score_outside
from imucal.gap.scoring import DiagnosisSettings
from imucal.gap.stress import render_stress_page, score_stress, stress_plan
from imucal.ingest import ingest_recording
from imucal.io import read_benchmark_seconds, read_json
from imucal.io.dataset import read_dataset
from imucal.pipeline.full import PipelineOptions, calibrate_session

#: Check -> (scoring function of (diagnoses, keys, **options), page renderer of the score).
CHECKS = {
    "blind": (score_blind, render_blind_page),
    "stress": (score_stress, render_stress_page),
    "outside": (score_outside, render_outside_page),
    "detection": (score_detection, render_detection_page),
}


#: The diagnosis's simulated checks, each planned from its config section.
CHECKS_PLANNED = ("blind", "stress", "outside", "detection")


def check_plan(check: str, settings: Mapping) -> list[dict]:
    """The sealed plan of a check: one spec per session (effects, truth preset, protocol).

    Parameters
    ----------
    check : str
        One of :data:`CHECKS_PLANNED`.
    settings : mapping
        The check's config section (schema defaults applied).
    """
    if check == "blind":
        return blind_plan(
            settings["seed"], settings["seeds_per_effect"], settings["n_null"],
            settings["unknown"], shapes=settings["shapes"],
        )  # fmt: skip
    if check == "stress":
        return stress_plan(settings["seed"], settings["seeds_alone"], settings["n_clean"])
    if check == "outside":
        return outside_plan(settings["seed"], settings["n_clean"])
    if check == "detection":
        return detection_plan(
            settings["seed"], settings["factors"], settings["seeds_per_level"],
            settings["effects"] or None, settings["n_clean"],
        )  # fmt: skip
    raise ValueError(f"unknown check {check!r}; expected one of {CHECKS_PLANNED}")


def score_check(
    check: str,
    diagnoses: Sequence[str | Path],
    sealed: Sequence[str | Path],
    benchmarks: Sequence[str | Path],
    detection_score: str | Path | None = None,
    **options,
) -> tuple[dict, str]:
    """Score one check's run.

    Parameters
    ----------
    check : {'blind', 'stress', 'outside', 'detection'}
    diagnoses, sealed, benchmarks : sequence of path
        The diagnosis JSONs, the answer keys (both named by session) and the diagnose rule's
        Snakemake benchmark files.
    detection_score : path, optional
        The blind check only: a detection sweep's ``score.json``; where the file exists, its
        detection limits are shown on the blind check's page (it is read, not required: the
        blind check does not run the sweep).
    **options
        Passed to the check's scoring function (detection: ``rate``, ``confidence``).

    Returns
    -------
    score : dict
        The check's score plus ``diagnosis_seconds``.
    page : str
        The check's self-contained HTML page.
    """
    if check not in CHECKS:
        raise ValueError(f"check {check!r}: expected one of {sorted(CHECKS)}")
    score_fn, render = CHECKS[check]
    by_session = {Path(f).stem: read_json(f) for f in diagnoses}
    keys = {Path(f).stem: read_json(f) for f in sealed}
    score = score_fn(by_session, keys, **options)
    score["diagnosis_seconds"] = read_benchmark_seconds(benchmarks)
    if check == "blind":
        present = detection_score is not None and Path(detection_score).is_file()
        return score, render(score, detection=read_json(detection_score) if present else None)
    return score, render(score)


def _where(err: BaseException) -> str:
    """The innermost frame of the package in the error's traceback, ``module:line function``."""
    frames = [f for f in traceback.extract_tb(err.__traceback__) if "imucal" in f.filename]
    if not frames:
        return ""
    f = frames[-1]
    module = Path(f.filename).as_posix().split("imucal/", 1)[-1]
    return f"imucal/{module}:{f.lineno} {f.name}"


def diagnose_folder(
    folder: str | Path,
    dataset: str,
    *,
    imucal_version: str,
    settings: DiagnosisSettings,
    pipeline: Mapping | None = None,
) -> dict:
    """Ingest a session folder, calibrate and diagnose it; record a failure instead of raising.

    Parameters
    ----------
    folder : str or Path
        Dataset folder (``dataset.yaml``).
    dataset : str
        Session name.
    imucal_version : str
        Package version stamped on the ingested tables.
    settings : DiagnosisSettings
    pipeline : dict, optional
        The workflow's pipeline settings (``exact_rotation``, ``lowpass_order``,
        ``lowpass_cutoff_hz``; :meth:`PipelineOptions.of_dataset`).

    Returns
    -------
    dict
        The diagnosis (diagnosis.json) plus ``calibration`` (the pipeline's calibration,
        :meth:`ImuCalibration.to_dict`, None when the pipeline failed or the data allow no
        complete calibration: ``calibration_incomplete`` then says why). When anything raises:
        :func:`~imucal.gap.blind.failed_diagnosis` with ``failed`` = ``"Type: message"``,
        ``failed_in`` ('pipeline' or 'diagnosis'), ``where`` (innermost package frame) and
        ``traceback``.

    Notes
    -----
    The pipeline runs once on its own (for the calibration and to tell a pipeline failure from
    a diagnosis failure) and once inside :func:`diagnose`: a few percent more time.
    """
    calibration = None
    try:
        info = read_dataset(folder)
        tables = {
            r: ingest_recording(path, r, info, imucal_version)[0]
            for r, path in info.recordings.items()
        }
        imu = {r: t for r, t in tables.items() if r in IMU_RECORDINGS}
        options = PipelineOptions.of_dataset(info, **(pipeline or {}))
        try:
            fit = calibrate_session(imu, tables.get("reference"), options)
            calibration, incomplete = fit.calibration.to_dict(), None
        except ValueError as err:  # the data allow no complete calibration: an outcome
            incomplete = str(err)
        result = diagnose(imu, tables.get("reference"), options, dataset=dataset, settings=settings)
    except Exception as err:  # noqa: BLE001 (a check scores every failure as a crash)
        result = failed_diagnosis(dataset, f"{type(err).__name__}: {err}")
        result.update(
            failed_in="pipeline" if calibration is None else "diagnosis",
            where=_where(err),
            traceback=traceback.format_exception(err),
        )
    else:
        result["calibration_incomplete"] = incomplete
    result["calibration"] = calibration
    return result
