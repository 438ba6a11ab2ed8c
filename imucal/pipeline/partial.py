"""Calibration of a partial session: run every stage the recordings allow, say why not the rest.

Public recordings rarely follow the paper's whole protocol (3-D platform, 12-position cube, rate
table, reference). This module decides, from the recordings, the sensors they hold and their
segments, which methods can run, runs them in dependency order and records every stage as
``run`` or ``skipped`` with the reason. A stage that applies but cannot be fitted from these data
(too few poses, a direction not excited, ...) is skipped with the fit's own message, so a partial
session never fails as a whole; errors that are not about the data (bugs) still propagate.

Methods per sensor, best first (the first that runs gives the final calibration):

- magnetometer: ellipsoid fit (step 1) + ``T_R,mag`` from the rotation3d phases (step 2); step 1
  alone leaves the field in the magnetometer's own (ellipsoid) frame;
- accelerometer: known orientations (six faces, Ferraris) in frame B of the positions; cube fit
  (eq. 32) on many static poses + ``T_R,acc`` from the rotation3d phases; the gravity direction
  of an orientation reference at rests (in the gyroscope's frame); the cube fit alone;
- gyroscope: rate table (eq. 33) + ``T_R,gyr``; known-angle rotations (Ferraris); against an
  orientation reference (motion capture, robot); pose to pose (Tedaldi et al. 2014) in the
  accelerometer's frame; tool-free (``T_R,gyr`` + eq. 36 scale);
  the bias alone.

The module is long (about 770 lines): one runner per stage of the registry that a partial
session can take, each with its condition and reason when it does not apply, and the choice of
the final calibration among them; they share the session's state (:class:`_Session`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pandas as pd

from imucal import errormodel, uncertainty
from imucal.calibration import SensorCalibration
from imucal.columns import ACC, GYR, MAG, SENSORS, TIME
from imucal.fits import accelerometer, gyroscope, orientations
from imucal.fits.propagation import upper_bias_covariance
from imucal.pipeline import stages
from imucal.pipeline.options import FitMethods
from imucal.pipeline.outcome import NOT_SHIPPED, not_run_reason
from imucal.pipeline.registry import FINAL, STAGES, VALIDATE, split_held_out
from imucal.segments.table import cut_finite, rows_of

#: Recordings whose magnetometer samples may feed the ellipsoid fit, preferred first.
MAG_RECORDINGS = ("tumble", "rotation3d", "cube", "poses", "ferraris", "static")
#: Recordings held at one orientation: they add one direction to the ellipsoid, and their
#: thousands of samples there would outweigh the turning recordings with an error that does not
#: average out over them (the reading's quantisation at a fixed field, a local field); offered
#: to the fit only when they are the only source (which the coverage check then refuses).
ONE_ORIENTATION = ("static",)
#: The cube fit has 9 parameters and one equation per position.
MIN_CUBE_POSITIONS = 9


class NotApplicable(Exception):
    """A stage's requirements are not met by the dataset (the message says which)."""


@dataclasses.dataclass
class Outcome:
    """What happened to one stage.

    Attributes
    ----------
    name : str
    status : {'run', 'skipped'}
    reason : str
        Why it was skipped, or what it used.
    artifact : dict or None
        The stage's JSON-ready result when it ran.
    """

    name: str
    status: str
    reason: str
    artifact: dict | None = None

    def summary(self) -> dict:
        return {
            "stage": self.name,
            "what": STAGES[self.name].what,
            "status": self.status,
            "reason": self.reason,
        }


def sensors_of(table: pd.DataFrame) -> tuple[str, ...]:
    """Sensors with at least one finite sample in an ingested table."""
    present = []
    for sensor, columns in (("acc", ACC), ("gyr", GYR), ("mag", MAG)):
        if (
            all(c in table.columns for c in columns)
            and np.isfinite(table[list(columns)].to_numpy(dtype=float)).all(axis=1).any()
        ):
            present.append(sensor)
    return tuple(present)


def _need(condition: bool, reason: str) -> None:
    if not condition:
        raise NotApplicable(reason)


class _Session:
    """The ingested tables, segments and the results so far of one partial session."""

    def __init__(
        self,
        tables: Mapping[str, pd.DataFrame],
        segments: pd.DataFrame,
        gravity_m_s2: float,
        field_norm: float,
        ratetable: Mapping | None,
        saturation_m_s2: float | None,
        saturation_rad_s: float | None,
        notes: Mapping[str, str],
        lowpass: Mapping[str, float],
        references: Mapping[str, tuple[pd.DataFrame, Mapping]] | None = None,
        reference_where: Mapping[str, str] | None = None,
        methods: FitMethods | None = None,
        exact_rotation: bool = True,
    ):
        self.methods = methods or FitMethods()
        self.exact = exact_rotation
        self.references = dict(references or {})
        # a held-out recording is validated on, never fitted on (registry.split_held_out)
        held = split_held_out(self.references)[1]
        self.tables = {k: v for k, v in tables.items() if k != "reference" and k not in held}
        self.held_out_tables = {k: tables[k] for k in held if k in tables}
        self.reference_where = dict(reference_where or {})
        self.segments = segments
        self.gravity_m_s2 = gravity_m_s2
        self.field_norm = field_norm
        self.ratetable = ratetable
        self.saturation_m_s2 = saturation_m_s2
        self.saturation_rad_s = saturation_rad_s
        self.sensors = {name: sensors_of(t) for name, t in self.tables.items()}
        self.notes = dict(notes)
        self.lowpass = dict(lowpass)
        self.done: dict[str, dict] = {}

    @functools.cached_property
    def rotation3d_lowpass(self) -> pd.DataFrame:
        """The low-pass filtered rotation3d recording (both alignment stages use it)."""
        from imucal.segments.filtering import lowpass_recording

        return lowpass_recording(self.tables["rotation3d"], **self.lowpass)

    def with_sensor(self, recording: str, sensor: str) -> bool:
        return recording in self.tables and sensor in self.sensors[recording]

    def has_phases(self, recording: str = "rotation3d") -> bool:
        return recording in self.tables and not rows_of(self.segments, recording, "phase").empty

    def need_phases(self, sensor: str) -> None:
        """Raise NotApplicable unless rotation3d has phases and ``sensor`` samples."""
        if self.has_phases() and self.with_sensor("rotation3d", sensor):
            return
        why = f"needs rotation3d phases about x, y, z with {sensor} samples"
        if "rotation3d" in self.notes:
            why += f" ({self.notes['rotation3d']})"
        elif "rotation3d" not in self.tables:
            why += " (no rotation3d recording)"
        raise NotApplicable(why)

    def poses(self, recording: str) -> pd.DataFrame:
        return rows_of(self.segments, recording, "position", "static")


# -- magnetometer --------------------------------------------------------------------------


def _mag_step1(s: _Session) -> dict:
    from imucal.fits import magnetometer

    sources = [r for r in MAG_RECORDINGS if s.with_sensor(r, "mag")]
    _need(bool(sources), "no recording has magnetometer samples")
    primary, extra = sources[0], [r for r in sources[1:] if r not in ONE_ORIENTATION]
    _, samples = magnetometer.field_samples(s.tables[primary])
    fit = magnetometer.fit_ellipsoid(
        samples,
        refine_lm=s.methods.mag_refine_lm,
        field_norm=s.field_norm,
        extra_samples={r: magnetometer.field_samples(s.tables[r])[1] for r in extra} or None,
    )
    return {**fit.to_dict(), "source": primary, "offered": extra}


def _mag_step2(s: _Session) -> dict:
    _need("mag_step1" in s.done, "needs the ellipsoid fit (mag_step1)")
    s.need_phases("mag")
    return stages.align_mag(
        s.tables["rotation3d"],
        s.segments,
        s.done["mag_step1"],
        method=s.methods.mag_alignment,
        exact=s.exact,
    )


# -- accelerometer -------------------------------------------------------------------------


def _acc_known_orientation(s: _Session) -> dict:
    from imucal.fits import ferraris

    _need(s.with_sensor("ferraris", "acc"), "needs a ferraris recording with accelerometer data")
    rows = s.poses("ferraris")
    _need("up" in rows.columns, "the ferraris segments carry no 'up' direction")
    rows = rows[rows["up"].notna() & (rows["up"].astype(str) != "")]
    _need(len(rows) >= 4, f"{len(rows)} static faces with a known up direction, expected >= 4")
    positions = [v for _, v in cut_finite(s.tables["ferraris"], rows, ACC)]
    directions = np.array([_axis_vector(str(u)) for u in rows["up"]])
    fit = ferraris.fit_known_orientations(
        positions, directions, s.gravity_m_s2, labels=[str(x) for x in rows["label"]]
    )
    artifact = stages.plain(fit)
    artifact.update(calibration=fit.calibration.to_dict(), gravity_m_s2=s.gravity_m_s2)
    if len(positions) >= ferraris.MIN_POSITIONS + 2:
        held = ferraris.heldout_positions(positions, directions, s.gravity_m_s2)
        artifact.update(heldout_error_m_s2=held.errors_m_s2.tolist(), heldout_z2=held.z2.tolist())
    return artifact


def _axis_vector(up: str) -> np.ndarray:
    """'+x', '-z', 'x' ... -> unit vector in B."""
    sign = -1.0 if up.startswith("-") else 1.0
    axis = up.lstrip("+-")
    if axis not in ("x", "y", "z"):
        raise ValueError(f"up direction {up!r}: expected '+x', '-x', ..., '-z'")
    v = np.zeros(3)
    v["xyz".index(axis)] = sign
    return v


def _pose_recording(s: _Session) -> str:
    for r in ("cube", "poses"):
        if s.with_sensor(r, "acc") and len(s.poses(r)) >= MIN_CUBE_POSITIONS:
            return r
    counts = {r: len(s.poses(r)) for r in ("cube", "poses") if r in s.tables}
    shown = [_coverage(s, r).reason for r in ("cube", "poses") if s.with_sensor(r, "acc")]
    raise NotApplicable(
        f"needs >= {MIN_CUBE_POSITIONS} static poses in a cube or poses recording with "
        f"accelerometer data (static poses found: {counts or 'no such recording'})"
        + "".join(f"; {reason}" for reason in shown if reason)
    )


def _coverage(s: _Session, recording: str) -> orientations.OrientationCoverage:
    """The distinct gravity directions of a recording's poses (those long enough for the fit)."""
    pieces = [v for _, v in cut_finite(s.tables[recording], s.poses(recording), ACC)]
    pieces = [v for v in pieces if len(v) >= accelerometer.MIN_SAMPLES_PER_POSITION]
    return orientations.cube_coverage(
        np.array([v.mean(axis=0) for v in pieces]).reshape(-1, 3),
        np.array([len(v) for v in pieces]),
    )


def _acc_cube(s: _Session) -> dict:
    recording = _pose_recording(s)
    coverage = _coverage(s, recording)
    _need(coverage.identifiable, coverage.reason)
    rows = s.poses(recording)
    positions = [v for _, v in cut_finite(s.tables[recording], rows, ACC)]
    fit = accelerometer.fit_cube(
        positions,
        s.gravity_m_s2,
        labels=[str(x) for x in rows["label"]],
        saturation_limit_m_s2=s.saturation_m_s2,
        method=s.methods.acc_cube,
    )
    artifact = stages.plain(fit)
    artifact.update(gravity_m_s2=s.gravity_m_s2, recording=recording)
    artifact["orientations"] = coverage.to_dict()
    if len(positions) > MIN_CUBE_POSITIONS:
        held = accelerometer.heldout_errors(positions, s.gravity_m_s2)
        artifact.update(
            heldout_error_before_m_s2=held.before.tolist(),
            heldout_error_after_m_s2=held.after.tolist(),
            heldout_predicted_std_m_s2=held.predicted_std.tolist(),
        )
    if recording in s.notes:  # how the poses were found (e.g. the tremor-adaptive detector)
        artifact["segmentation"] = s.notes[recording]
    artifact["calibration"] = stages.cube_calibration(artifact).to_dict()
    return artifact


def _acc_align(s: _Session) -> dict:
    _need("acc_cube" in s.done, "needs the cube fit (acc_cube)")
    s.need_phases("acc")
    return stages.align_acc(
        s.rotation3d_lowpass,
        s.segments,
        s.done["acc_cube"],
        method=s.methods.acc_alignment,
        exact=s.exact,
    )


# -- gyroscope -----------------------------------------------------------------------------


def _static_gyr(s: _Session) -> list[np.ndarray]:
    names = (
        ["static"]
        if s.with_sensor("static", "gyr")
        else [r for r in s.tables if s.with_sensor(r, "gyr")]
    )
    pieces = []
    for name in names:
        rows = rows_of(s.segments, name, "static", "position")
        pieces += [v for _, v in cut_finite(s.tables[name], rows, GYR) if len(v) >= 2]
    return pieces


def _gyr_bias(s: _Session) -> dict:
    found = _static_gyr(s)
    # the segmentation's word on rests too short to count names the settings that find them
    hints = [n for r, n in s.notes.items() if r in s.tables and "still interval" in n]
    _need(bool(found), "; ".join(["no static segment with gyroscope samples", *hints]))
    pieces, _, left_out = gyroscope.usable_static_segments(found)
    _need(
        bool(pieces),
        f"no static segment with at least {gyroscope.MIN_STATIC_SAMPLES} gyroscope samples "
        f"({left_out['short_left_out']} shorter ones)",
    )
    artifact = stages.plain(gyroscope.estimate_bias(pieces))
    return {**artifact, **left_out} if left_out["short_left_out"] else artifact


def _bias(s: _Session) -> np.ndarray:
    return stages.gyr_bias_value(s.done["gyr_bias"], s.methods.gyr_bias_estimator)[0]


def _gyr_table(s: _Session) -> dict:
    _need(
        s.with_sensor("ratetable", "gyr") and s.ratetable is not None, "needs a ratetable recording"
    )
    artifact, _ = stages.fit_gyr_table(
        s.tables["ratetable"],
        s.segments,
        saturation_limit_rad_s=np.inf if s.saturation_rad_s is None else s.saturation_rad_s,
    )
    return artifact


def _gyr_align(s: _Session) -> dict:
    _need("gyr_bias" in s.done, "needs the gyroscope bias")
    s.need_phases("gyr")
    return stages.align_gyr(
        s.rotation3d_lowpass,
        s.segments,
        _bias(s),
        method=s.methods.gyr_alignment,
        exact=s.exact,
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


def _gyr_known_rotation(s: _Session) -> dict:
    from imucal.fits import ferraris

    _need("gyr_bias" in s.done, "needs the gyroscope bias")
    recording, rows = None, None
    for name in ("ferraris", "rotation3d"):
        if s.with_sensor(name, "gyr"):
            rows = rows_of(s.segments, name, "phase")
            if "angle_deg" in rows.columns:
                rows = rows[np.isfinite(rows["angle_deg"].astype(float))]
            if "angle_deg" in rows.columns and len(rows):
                recording = name
                break
    _need(
        recording is not None,
        "needs rotation sections of known angle (a ferraris recording, "
        "or rotation3d phases with angle_deg) with gyroscope data",
    )
    _need(len(rows) >= 3, f"{len(rows)} rotation sections with a known angle, expected >= 3")
    known = np.array(
        [np.radians(float(r.angle_deg)) * _axis_vector(str(r.axis)) for r in rows.itertuples()]
    )
    # the integrals' white noise is the static recording's sample noise; the bias's std (its
    # wander added where the blocks show it) enters every integral times its duration
    bias, bias_std = stages.gyr_bias_value(s.done["gyr_bias"], s.methods.gyr_bias_estimator)
    fit = ferraris.fit_known_rotations(
        cut_finite(s.tables[recording], rest_to_rest(s.segments, recording, rows), GYR),
        known,
        bias,
        noise_std_rad_s=np.asarray(s.done["gyr_bias"]["noise_std_rad_s"], dtype=float),
        bias_std_rad_s=bias_std,
        labels=[str(x) for x in rows["label"]],
    )
    artifact = stages.plain(fit)
    artifact.update(recording=recording, calibration=fit.calibration.to_dict())
    return artifact


def _gyr_reference(s: _Session) -> dict:
    from imucal.pipeline.reference import fit_gyr_reference

    _need(bool(s.references), "needs a recording declared with an orientation reference")
    where = {r: s.reference_where.get(r, f"recordings.{r}.reference") for r in s.references}
    # without rests the fit finds its own bias; with them, the bias alone is its fallback
    rests = stages.gyr_bias_value(s.done["gyr_bias"], "ls") if "gyr_bias" in s.done else None
    return fit_gyr_reference({**s.tables, **s.held_out_tables}, s.references, rests, where)


def _acc_reference(s: _Session) -> dict:
    from imucal.pipeline.reference import fit_acc_reference

    _need("gyr_reference" in s.done, "needs the gyroscope against the reference (gyr_reference)")
    return fit_acc_reference(
        s.tables, s.references, s.segments, s.done["gyr_reference"], s.gravity_m_s2
    )


def _mag_reference(s: _Session) -> dict:
    from imucal.pipeline.reference import fit_mag_reference

    _need("mag_step1" in s.done, "needs the ellipsoid fit (mag_step1)")
    _need("gyr_reference" in s.done, "needs the gyroscope against the reference (gyr_reference)")
    return fit_mag_reference(s.tables, s.references, s.done["mag_step1"], s.done["gyr_reference"])


def _acc_final(s: _Session) -> SensorCalibration | None:
    for stage in FINAL["acc"]:
        if stage in s.done:
            return SensorCalibration.from_dict("acc", s.done[stage]["calibration"])
    return None


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


def _gyr_pose_to_pose(s: _Session) -> dict:
    from imucal.fits import posetopose

    _need("gyr_bias" in s.done, "needs the gyroscope bias")
    acc = _acc_final(s)
    _need(acc is not None, "needs an accelerometer calibration for the gravity directions")
    recording = next(
        (
            r
            for r in ("poses", "cube")
            if s.with_sensor(r, "gyr") and s.with_sensor(r, "acc") and len(s.poses(r)) >= 6
        ),
        None,
    )
    _need(
        recording is not None,
        "needs >= 6 static poses in a poses or cube recording with "
        "accelerometer and gyroscope data",
    )
    directions, intervals = pose_intervals(s.tables[recording], s.poses(recording), acc)
    fit = posetopose.fit_pose_to_pose(
        directions[:-1],
        directions[1:],
        intervals,
        _bias(s),
        bias_std_rad_s=stages.gyr_bias_value(s.done["gyr_bias"], s.methods.gyr_bias_estimator)[1],
        direction_covariance=pose_direction_covariance(
            s.tables[recording], s.poses(recording), acc
        ),
    )
    artifact = stages.plain(fit)
    artifact.update(recording=recording, calibration=fit.calibration.to_dict())
    return artifact


def _gyr_scale(s: _Session) -> dict:
    _need("gyr_align" in s.done, "needs the gyroscope alignment (gyr_align)")
    _need(
        "mag_step2" in s.done or "acc_align" in s.done,
        "needs a calibrated magnetometer (mag_step2) or accelerometer (acc_align) to measure "
        "the phase angles",
    )
    return stages.estimate_gyr_scale(
        s.tables["rotation3d"],
        s.rotation3d_lowpass,
        s.segments,
        s.done["gyr_bias"],
        s.done["gyr_align"],
        s.done.get("acc_align"),
        s.done.get("mag_step2"),
        bias_estimator=s.methods.gyr_bias_estimator,
    )


RUNNERS: dict[str, Callable[[_Session], dict]] = {
    "mag_step1": _mag_step1,
    "mag_step2": _mag_step2,
    "acc_known_orientation": _acc_known_orientation,
    "acc_cube": _acc_cube,
    "acc_align": _acc_align,
    "gyr_bias": _gyr_bias,
    "gyr_table": _gyr_table,
    "gyr_align": _gyr_align,
    "gyr_known_rotation": _gyr_known_rotation,
    "gyr_reference": _gyr_reference,
    "acc_reference": _acc_reference,
    "mag_reference": _mag_reference,
    "gyr_pose_to_pose": _gyr_pose_to_pose,
    "gyr_scale": _gyr_scale,
}


def run_stages(
    tables: Mapping[str, pd.DataFrame],
    segments: pd.DataFrame,
    *,
    gravity_m_s2: float,
    field_norm: float = 1.0,
    ratetable: Mapping | None = None,
    saturation_m_s2: float | None = None,
    saturation_rad_s: float | None = None,
    notes: Mapping[str, str] | None = None,
    lowpass_order: int = 4,
    lowpass_cutoff_hz: float = 5.0,
    references: Mapping[str, tuple[pd.DataFrame, Mapping]] | None = None,
    reference_where: Mapping[str, str] | None = None,
    methods: FitMethods | None = None,
    exact_rotation: bool = True,
) -> list[Outcome]:
    """Run every stage the session allows, in :data:`STAGES` order.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Ingested recordings by name (SI units; absent sensors have no columns).
    segments : DataFrame
        Segments table of the session (automatic or from a section list).
    gravity_m_s2, field_norm : float
    ratetable : mapping, optional
        ``dataset.ratetable``.
    saturation_m_s2, saturation_rad_s : float, optional
        Sensor ranges; samples at them are left out of the fits that check it. None: the
        recordings' ranges are unknown (readers of SI data), nothing is left out.
    notes : mapping of str to str, optional
        Segmentation notes per recording (why its protocol was not found); they join the
        reasons of the stages that needed it.
    lowpass_order, lowpass_cutoff_hz : int, float
        Zero-phase Butterworth low-pass of rotation3d before the alignment stages (the
        workflow's ``lowpass`` config), cutoff in Hz.
    references : mapping, optional
        Recording -> (ingested orientation reference, its metadata) for the stage
        ``gyr_reference`` (:mod:`imucal.pipeline.reference`).
    reference_where : mapping, optional
        Recording -> key path of its reference in dataset.yaml (error messages).
    methods : FitMethods, optional
        The method of each fit (the workflow's config; defaults when None).
    exact_rotation : bool
        Exact rotation in the alignments (else the paper's small-angle form, eq. 5).

    Returns
    -------
    list of Outcome
        One per stage of :data:`STAGES`.
    """
    session = _Session(
        tables,
        segments,
        gravity_m_s2,
        field_norm,
        ratetable,
        saturation_m_s2,
        saturation_rad_s,
        notes or {},
        {"order": lowpass_order, "cutoff_hz": lowpass_cutoff_hz},
        references,
        reference_where,
        methods,
        exact_rotation,
    )
    outcomes = []
    for name, runner in RUNNERS.items():
        try:
            artifact = runner(session)
        except NotApplicable as why:
            outcomes.append(Outcome(name, "skipped", f"not applicable: {why}"))
            continue
        except ValueError as err:  # the fit's own message: too little or degenerate data
            outcomes.append(Outcome(name, "skipped", f"could not be fitted: {err}"))
            continue
        # a calibration that does worse than nominal on left-out data, or lies outside its
        # sensor's physical bounds on weak data, is not shipped (the sensor's next, simpler
        # stage is); one outside them on strong data or undetermined carries a warning
        review = _review(name, {**session.done, name: artifact}, session.methods, session.exact)
        if review["refuse"]:
            reason = f"{NOT_SHIPPED}: " + "; ".join(review["refuse"])
            outcomes.append(Outcome(name, "skipped", reason))
            continue
        # (a stage shared with the full protocol may have warned of the same value already)
        known = " ".join(artifact.get("warnings", []))
        warn = [f"{name}: {w}" for w in review["warn"]]
        warn = [w for w in warn if w.split(" against ")[0] not in known]
        if warn:
            artifact["warnings"] = [*artifact.get("warnings", []), *warn]
        session.done[name] = artifact
        what = STAGES[name].what
        if "fallback" in artifact:  # the fit did worse than its fallback, which is shipped
            what += f"; fitted but not shipped ({artifact['fallback']['shipped']} is): "
            what += artifact["fallback"]["reason"]
        outcomes.append(Outcome(name, "run", what, artifact))
    return outcomes


def _review(
    name: str, done: Mapping[str, dict], methods: FitMethods | None = None, exact: bool = True
) -> dict[str, list[str]]:
    """Refusals and warnings of a stage's calibration
    (:func:`imucal.validation.plausibility.review_fit`); none for stages that do not calibrate
    a sensor."""
    from imucal.validation.plausibility import review_fit

    sensor = STAGES[name].sensor
    if name not in FINAL.get(sensor, ()):
        return {"refuse": [], "warn": []}
    calibration = _calibration_of(name, done, methods or FitMethods(), exact)
    return review_fit(sensor, calibration, done[name])


#: Stages whose result is a sensor's final calibration, best first.


def final_calibration(
    outcomes: list[Outcome], methods: FitMethods | None = None, exact_rotation: bool = True
) -> dict[str, Any]:
    """The best calibration per sensor from the stages that ran, and why a sensor has none.

    Parameters
    ----------
    outcomes : list of Outcome
        :func:`run_stages`'s.
    methods : FitMethods, optional
        The methods the stages ran with (the gyro bias estimator picks the bias).
    exact_rotation : bool
        As the stages ran (the tool-free gyroscope's combination).

    Returns
    -------
    dict
        ``sensors``: sensor -> {'stage', 'calibration' (SensorCalibration dict)};
        ``missing``: sensor -> reason.
    """
    done = {o.name: o.artifact for o in outcomes if o.status == "run"}
    sensors, missing = {}, {}
    for sensor in SENSORS:
        stage = next((s for s in FINAL[sensor] if s in done), None)
        if stage is None:
            missing[sensor] = "no stage of this sensor could run: " + "; ".join(
                f"{o.name}: {o.reason}" for o in outcomes if o.name in FINAL[sensor]
            )
            continue
        calibration = _calibration_of(stage, done, methods or FitMethods(), exact_rotation)
        sensors[sensor] = {"stage": stage, "calibration": calibration}
    return {"sensors": sensors, "missing": missing}


def _calibration_of(stage: str, done: Mapping[str, dict], methods: FitMethods, exact: bool) -> dict:
    artifact = done[stage]
    if stage == "mag_step1":
        from imucal.fits import magnetometer

        fit = magnetometer.EllipsoidFit.from_dict(dict(artifact))
        cov = uncertainty.step1_only_covariance(fit.upper, fit.bias, fit.selected.covariance)
        return SensorCalibration(
            "mag",
            fit.bias,
            fit.upper,
            "normalised",
            uncertainty.std_of(cov),
            "ellipsoid fit only (step 1, no T_R)",
            cov,
        ).to_dict()
    if stage == "gyr_table":
        shift = np.asarray(artifact.get("cut_shift", np.zeros(12)), dtype=float)
        cov9 = upper_bias_covariance(
            artifact["matrix"], np.asarray(artifact["covariance"]) + np.outer(shift, shift)
        )
        cov = uncertainty.step1_only_covariance(artifact["upper"], artifact["bias"], cov9)
        return SensorCalibration(
            "gyr",
            artifact["bias"],
            artifact["upper"],
            "rad/s",
            uncertainty.std_of(cov),
            "rate table (eq. 33), no T_R",
            cov,
        ).to_dict()
    if stage == "gyr_scale":
        return stages.tool_free_gyr(
            done["gyr_bias"], artifact, bias_estimator=methods.gyr_bias_estimator, exact=exact
        ).to_dict()
    if stage == "gyr_bias":
        # the wander's variance where it shows
        bias, std = stages.gyr_bias_value(artifact, methods.gyr_bias_estimator)
        return SensorCalibration(
            "gyr",
            bias,
            np.eye(3),
            "rad/s",
            {"bias": std},
            "bias only (nominal scale, sensor frame)",
            quality=stages.gyr_bias_quality(artifact),
        ).to_dict()
    return dict(artifact["calibration"])


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
