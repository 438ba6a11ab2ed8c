"""The gyroscope runners of the partial path: the bias, the rate table, ``T_R,gyr``, known-angle
rotations (Ferraris), an orientation reference, pose to pose (Tedaldi et al. 2014) and the
tool-free scale (eq. 36), with the rests and pose intervals they are cut from. Each raises
:class:`~imucal.pipeline.partial.session.NotApplicable` with the reason when the session does
not allow it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from imucal import errormodel, uncertainty
from imucal.calibration import SensorCalibration
from imucal.columns import ACC, GYR, TIME
from imucal.pipeline import stages
from imucal.pipeline.partial.accelerometer import acc_final
from imucal.pipeline.partial.session import Session, axis_vector, need
from imucal.segments.table import cut_finite, rows_of


def gyr_bias(s: Session, done: Mapping[str, dict]) -> dict:
    return s.run_node("gyr_bias", **s.tables, segments=s.segments)


def _bias(s: Session, done: Mapping[str, dict]) -> np.ndarray:
    return stages.gyr_bias_value(done["gyr_bias"], s.methods.gyr_bias_estimator)[0]


def gyr_table(s: Session, done: Mapping[str, dict]) -> dict:
    need(
        s.with_sensor("ratetable", "gyr") and s.ratetable is not None, "needs a ratetable recording"
    )
    return s.run_node("gyr_table", ratetable=s.tables["ratetable"], segments=s.segments)


def gyr_align(s: Session, done: Mapping[str, dict]) -> dict:
    need("gyr_bias" in done, "needs the gyroscope bias")
    s.need_phases("gyr")
    return s.run_node(
        "gyr_align", lowpass=s.rotation3d_lowpass, segments=s.segments, gyr_bias=done["gyr_bias"]
    )


#: A rest this many samples or fewer away from a rotation section is next to it.
ADJACENT_SAMPLES = 2


def rest_to_rest(segments: pd.DataFrame, recording: str, rows: pd.DataFrame) -> pd.DataFrame:
    """Rotation sections widened to the middles of the rests (static or position) beside them.

    A rest ends where the rate passes the segmentation's threshold, so it takes in the slow
    start and end of a turn (about 0.1 s of a 1.5-s cosine ramp); a section cut there misses
    that part of the turn, an error of the same sign in every section (the scale about 5e-5 too
    large for 720-deg turns, as large as its standard deviation). From the middle of the rest
    before to the middle of the rest after, the integral holds the whole turn, at the price of
    the rests' noise and the bias's error over them (both in the fit's covariance). A section
    without a rest right next to it (ending or starting within :data:`ADJACENT_SAMPLES` of it)
    keeps its bounds: a rest farther away has other motion between (declared sections of a
    recording handled between them), which the integral must not take in.

    Parameters
    ----------
    segments : DataFrame
        The session's segments table.
    recording : str
    rows : DataFrame
        Rows of ``segments`` of ``recording`` to widen.

    Returns
    -------
    DataFrame
        ``rows`` with ``start_index`` / ``end_index`` moved (sample indices; ``start_s`` and
        ``end_s`` unchanged).
    """
    every = segments[segments["recording"] == recording].sort_values("start_index")
    starts = every["start_index"].to_numpy(int)
    ends = every["end_index"].to_numpy(int)
    rest = every["kind"].isin(("static", "position")).to_numpy()
    middles = (starts + ends) // 2
    out = rows.copy()
    for i, r in zip(rows.index, rows.itertuples(index=False)):
        before = np.flatnonzero(ends <= int(r.start_index))
        after = np.flatnonzero(starts >= int(r.end_index))
        if (
            before.size
            and rest[before[-1]]
            and r.start_index - ends[before[-1]] <= ADJACENT_SAMPLES
        ):
            out.loc[i, "start_index"] = middles[before[-1]]
        if after.size and rest[after[0]] and starts[after[0]] - r.end_index <= ADJACENT_SAMPLES:
            out.loc[i, "end_index"] = middles[after[0]] + 1
    return out


def gyr_known_rotation(s: Session, done: Mapping[str, dict]) -> dict:
    from imucal.fits import ferraris

    need("gyr_bias" in done, "needs the gyroscope bias")
    recording, rows = None, None
    for name in ("ferraris", "rotation3d"):
        if s.with_sensor(name, "gyr"):
            rows = rows_of(s.segments, name, "phase")
            if "angle_deg" in rows.columns:
                rows = rows[np.isfinite(rows["angle_deg"].astype(float))]
            if "angle_deg" in rows.columns and len(rows):
                recording = name
                break
    need(
        recording is not None,
        "needs rotation sections of known angle (a ferraris recording, "
        "or rotation3d phases with angle_deg) with gyroscope data",
    )
    sections = cut_finite(s.tables[recording], rest_to_rest(s.segments, recording, rows), GYR)
    hit = _clipped_turns([w for _, w in sections], s.saturation_rad_s)
    clipped = [str(label) for label, h in zip(rows["label"], hit) if h]
    rows, sections = rows[~hit], [c for c, h in zip(sections, hit) if not h]
    need(
        len(rows) >= 3,
        f"{len(rows)} rotation sections with a known angle"
        + (f" without clipped readings ({len(clipped)} left out)" if clipped else "")
        + ", expected >= 3",
    )
    known = np.array(
        [np.radians(float(r.angle_deg)) * axis_vector(str(r.axis)) for r in rows.itertuples()]
    )
    # the integrals' white noise is the static recording's sample noise; the bias's std (its
    # wander added where the blocks show it) enters every integral times its duration
    bias, bias_std = stages.gyr_bias_value(done["gyr_bias"], s.methods.gyr_bias_estimator)
    fit = ferraris.fit_known_rotations(
        sections,
        known,
        bias,
        noise_std_rad_s=np.asarray(done["gyr_bias"]["noise_std_rad_s"], dtype=float),
        bias_std_rad_s=bias_std,
        labels=[str(x) for x in rows["label"]],
    )
    artifact = stages.plain(fit)
    artifact.update(recording=recording, calibration=fit.calibration.to_dict())
    return _with_clipped(artifact, clipped, "rotation sections")


def _clipped_turns(readings: list[np.ndarray], limit_rad_s: float | None) -> np.ndarray:
    """Which turns have gyro readings (m, 3 each, rad/s) at the sensor's range, shape (n_turn,).

    A clipped reading is smaller than the rate it stands for, so the angle integrated over its
    turn is too small by an unknown amount: such a turn would pull the scale fitted on it (a
    few degrees on a 90-degree turn is a few per cent of scale, far beyond its standard
    deviation). All False when the range is not known (recordings in SI units).
    """
    if limit_rad_s is None:
        return np.zeros(len(readings), dtype=bool)
    return np.array([bool(stages.at_range(w, limit_rad_s).any()) for w in readings], dtype=bool)


def _with_clipped(artifact: dict, clipped: list[str], what: str) -> dict:
    """The artifact with the turns left out for clipped readings, and a warning naming them."""
    if clipped:
        artifact["left_out_clipped"] = clipped
        artifact.setdefault("warnings", []).append(
            f"{len(clipped)} {what} left out: their gyroscope readings reach the sensor's range "
            f"(clipped, so their integrated angle is too small): {', '.join(clipped)}"
        )
    return artifact


def gyr_reference(s: Session, done: Mapping[str, dict]) -> dict:
    from imucal.pipeline.reference import fit_gyr_reference

    need(bool(s.references), "needs a recording declared with an orientation reference")
    where = {r: s.reference_where.get(r, f"recordings.{r}.reference") for r in s.references}
    # without rests the fit finds its own bias; with them, the bias alone is its fallback
    rests = stages.gyr_bias_value(done["gyr_bias"], "ls") if "gyr_bias" in done else None
    return fit_gyr_reference({**s.tables, **s.held_out_tables}, s.references, rests, where)


def pose_intervals(
    table: pd.DataFrame, rows: pd.DataFrame, acc: SensorCalibration
) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """Calibrated gravity direction per pose and the raw gyro (t, w) between consecutive poses.

    Returns
    -------
    directions : ndarray, shape (n_pose, 3)
        Unit up direction at each pose in frame B (mean of the calibrated accelerometer).
    intervals : list of (ndarray (m,), ndarray (m, 3))
        Times (s) and rad/s readings from the middle sample of pose k to that of pose k + 1.

    Notes
    -----
    A pose's segment ends where the rate passes the segmentation's threshold, so it takes in
    the slow start of the next motion; an interval from its last sample would miss that part
    of every turn (the scale about 2e-4 too large on the simulated handling, 1.3 times its
    standard deviation). From the middle of one pose to the middle of the next the increment
    holds the whole turn; the rests add only their noise and the bias's error over them.
    """
    directions = []
    for _, v in cut_finite(table, rows, ACC):
        mean = errormodel.apply(acc.matrix, acc.bias, v).mean(axis=0)
        directions.append(mean / np.linalg.norm(mean))
    t = table[TIME].to_numpy(dtype=float)
    w = table[list(GYR)].to_numpy(dtype=float)
    intervals = []
    middles = (rows["start_index"].to_numpy(int) + rows["end_index"].to_numpy(int)) // 2
    for first, last in zip(middles[:-1], middles[1:]):
        sl = slice(first, last + 1)
        keep = np.isfinite(w[sl]).all(axis=1)
        intervals.append((t[sl][keep], w[sl][keep]))
    return np.array(directions), intervals


def pose_direction_covariance(
    table: pd.DataFrame, rows: pd.DataFrame, acc: SensorCalibration
) -> np.ndarray | None:
    """Covariance of the poses' gravity directions from the accelerometer calibration's.

    The calibration's error moves every direction of :func:`pose_intervals` at once; the
    pose-to-pose fit absorbs most of it, so its residuals cannot show it.

    Returns
    -------
    ndarray, shape (6 (n_pose - 1), 6 (n_pose - 1)), or None
        Over ``(directions[:-1].ravel(), directions[1:].ravel())`` (the intervals' start and
        end directions), by the delta method from the covariance of the calibration's bias and
        matrix; None when the calibration has no covariance.
    """
    if acc.covariance is None:
        return None
    means = np.array([v.mean(axis=0) for _, v in cut_finite(table, rows, ACC)])

    def chain(p: np.ndarray) -> np.ndarray:
        up = (means - p[:3]) @ p[3:].reshape(3, 3).T
        up /= np.linalg.norm(up, axis=1, keepdims=True)
        return np.concatenate([up[:-1].ravel(), up[1:].ravel()])

    return uncertainty.propagate(
        chain, np.concatenate([acc.bias, acc.matrix.ravel()]), acc.covariance[:12, :12]
    )


def gyr_pose_to_pose(s: Session, done: Mapping[str, dict]) -> dict:
    from imucal.fits import posetopose

    need("gyr_bias" in done, "needs the gyroscope bias")
    acc = acc_final(done)
    need(acc is not None, "needs an accelerometer calibration for the gravity directions")
    recording = next(
        (
            r
            for r in ("poses", "cube")
            if s.with_sensor(r, "gyr") and s.with_sensor(r, "acc") and len(s.poses(r)) >= 6
        ),
        None,
    )
    need(
        recording is not None,
        "needs >= 6 static poses in a poses or cube recording with "
        "accelerometer and gyroscope data",
    )
    poses = s.poses(recording)
    directions, intervals = pose_intervals(s.tables[recording], poses, acc)
    covariance = pose_direction_covariance(s.tables[recording], poses, acc)
    labels = poses["label"].astype(str).tolist()
    names = [f"{a}-{b}" for a, b in zip(labels[:-1], labels[1:])]
    keep = ~_clipped_turns([w for _, w in intervals], s.saturation_rad_s)
    clipped = [name for name, k in zip(names, keep) if not k]
    need(
        keep.sum() >= posetopose.MIN_INTERVALS,
        f"{keep.sum()} of {len(names)} turns between poses without clipped gyroscope readings, "
        f"expected >= {posetopose.MIN_INTERVALS} (a clipped turn's integrated angle is too "
        "small)",
    )
    if covariance is not None:  # over (start directions, end directions), three per turn
        rows = np.flatnonzero(np.repeat(np.concatenate([keep, keep]), 3))
        covariance = covariance[np.ix_(rows, rows)]
    fit = posetopose.fit_pose_to_pose(
        directions[:-1][keep],
        directions[1:][keep],
        [interval for interval, k in zip(intervals, keep) if k],
        _bias(s, done),
        bias_std_rad_s=stages.gyr_bias_value(done["gyr_bias"], s.methods.gyr_bias_estimator)[1],
        direction_covariance=covariance,
    )
    artifact = stages.plain(fit)
    artifact.update(recording=recording, calibration=fit.calibration.to_dict())
    return _with_clipped(artifact, clipped, "turns between poses")


def gyr_scale(s: Session, done: Mapping[str, dict]) -> dict:
    need("gyr_align" in done, "needs the gyroscope alignment (gyr_align)")
    return s.run_node(
        "gyr_scale",
        rotation3d=s.tables["rotation3d"],
        lowpass=s.rotation3d_lowpass,
        segments=s.segments,
        gyr_bias=done["gyr_bias"],
        gyr_align=done["gyr_align"],
        acc_align=done.get("acc_align"),
        mag_step2=done.get("mag_step2"),
    )
