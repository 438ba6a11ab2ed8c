"""The segments table of a dataset: automatic segmentation of each recording by its protocol,
or the manual override of ``dataset.yaml``.

The paper (Zhang et al. 2014) segments by hand; the rules here are the implementer's:

* the static detector (quiet windows, static intervals at the rest level, motions):
  :mod:`imucal.segments.detector`;
* rotation3d phases, cube positions, the static recording and hand-placed poses:
  :mod:`imucal.segments.protocol`; rate-table runs: :mod:`imucal.segments.ratetable`; holds of
  poses held by hand: :mod:`imucal.segments.holds`;
* this module dispatches each recording to its segmenter (:func:`segment_recording`), takes the
  segments of ``dataset.yaml`` or of a section list instead where they are given
  (:func:`manual_segments`), and builds the dataset's table (:func:`segment_dataset`), where a
  partial session's recording whose protocol is not found keeps its static poses.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pandas as pd

from imucal.columns import ACC, GYR, KINDS, TIME, column_values
from imucal.constants import IMU_RECORDINGS, OTHER_RECORDINGS
from imucal.fits.accelerometer import MIN_SAMPLES_PER_POSITION
from imucal.fits.orientations import OrientationCoverage, cube_coverage
from imucal.segments.detector import SHORT_WINDOW_S, DetectorSettings, find_short_rests
from imucal.segments.protocol import segment_cube, segment_poses, segment_rotation3d, segment_static
from imucal.segments.ratetable import segment_ratetable
from imucal.segments.table import segment_row, segments_frame, to_table_rows

logger = logging.getLogger(__name__)


def manual_segments(recording: str, t_s: np.ndarray, entries: list[dict]) -> pd.DataFrame:
    """Segments given by hand in ``dataset.yaml`` for one recording.

    Parameters
    ----------
    recording : str
    t_s : ndarray, shape (n,)
        Timestamps of the ingested recording, s.
    entries : list of dict
        ``segments:`` entries of ``dataset.yaml`` naming this recording (keys ``label``, ``kind``,
        ``start_s``, ``end_s``, optional ``axis``, ``rate_dps``, ``up``, ``angle_deg``), or the
        entries of a section list (:func:`imucal.io.readers.read_sections`).

    Returns
    -------
    DataFrame
        Segments table rows; rows ``start_index`` .. ``end_index`` are the samples with
        ``start_s <= t_s <= end_s``. ``sense`` is 0 and ``turns`` NaN (not measured).

    Raises
    ------
    ValueError
        If an interval is empty, reversed or outside the recording, or a label repeats.
    """
    t = np.asarray(t_s, dtype=float)
    rows = []
    for e in entries:
        if e["kind"] not in KINDS:
            raise ValueError(
                f"manual segment {e['label']!r}: kind {e['kind']!r}, expected one of {KINDS}"
            )
        a = int(np.searchsorted(t, e["start_s"], side="left"))
        b = int(np.searchsorted(t, e["end_s"], side="right"))
        if not e["start_s"] < e["end_s"] or b - a < 2:
            raise ValueError(
                f"manual segment {recording}/{e['label']}: {e['start_s']}-{e['end_s']} s holds "
                f"{max(b - a, 0)} sample(s) of {t[0]:.2f}-{t[-1]:.2f} s; expected start_s < end_s "
                "and at least 2 samples inside the recording"
            )
        rate = e.get("rate_dps", np.nan)
        rows.append(
            segment_row(
                recording,
                e["label"],
                e["kind"],
                t,
                a,
                b,
                e.get("axis", ""),
                rate,
                up=e.get("up", ""),
                angle_deg=e.get("angle_deg", np.nan),
            )
        )
    frame = segments_frame(rows)
    dup = frame["label"][frame["label"].duplicated()].tolist()
    if dup:
        raise ValueError(
            f"manual segments of {recording}: label(s) {dup} repeat; expected unique labels"
        )
    return frame.sort_values("start_s", kind="stable").reset_index(drop=True)


def segment_recording(
    recording: str,
    table: pd.DataFrame,
    *,
    ratetable: dict | None = None,
    settings: DetectorSettings = DetectorSettings(),
) -> pd.DataFrame:
    """Automatic segments of one ingested recording (dispatch on its protocol name).

    Parameters
    ----------
    recording : str
        One of ``IMU_RECORDINGS``.
    table : DataFrame
        Ingested recording (``t_s``, ``acc_*``, ``gyr_*`` in SI units).
    ratetable : dict, optional
        ``{'axes': [...], 'rates_dps': [...]}``; required for ``ratetable``.
    settings : DetectorSettings

    Returns
    -------
    DataFrame
        Segments table rows of this recording.
    """
    if recording not in IMU_RECORDINGS + OTHER_RECORDINGS:
        raise ValueError(
            f"recording {recording!r}: expected one of {IMU_RECORDINGS + OTHER_RECORDINGS}"
        )
    if recording in OTHER_RECORDINGS:
        return _segment_pose_recording(recording, table, settings)
    missing = [c for c in (*ACC, *GYR) if c not in table.columns]
    if missing:
        raise ValueError(
            f"{recording}: no column(s) {missing}; the automatic segmentation needs the "
            "accelerometer and the gyroscope (give a section list or manual segments instead)"
        )
    t = table[TIME].to_numpy(dtype=float)
    acc = column_values(table, ACC)
    gyr = column_values(table, GYR)
    # streams merged on time leave rows without an acc/gyr sample (NaN): segment the rows with
    # both, then give the indices in rows of the whole table
    rows = np.flatnonzero(np.isnan(acc).all(axis=1) | np.isnan(gyr).all(axis=1))
    keep = np.setdiff1d(np.arange(t.size), rows) if rows.size else None
    if keep is not None:
        t, acc, gyr = t[keep], acc[keep], gyr[keep]
    if recording == "rotation3d":
        out = segment_rotation3d(t, acc, gyr, settings)
    elif recording == "cube":
        out = segment_cube(t, acc, gyr, settings)
    elif recording == "static":
        out = segment_static(t, acc, gyr, settings)
    elif ratetable is None:
        raise ValueError("recording 'ratetable' needs the table's axes and rates_dps; got none")
    else:
        out = segment_ratetable(t, acc, gyr, ratetable["axes"], ratetable["rates_dps"], settings)
    return out if keep is None else to_table_rows(out, keep)


def _segment_pose_recording(
    recording: str, table: pd.DataFrame, settings: DetectorSettings
) -> pd.DataFrame:
    """Static poses of a recording with an accelerometer (and maybe a gyroscope), else none."""
    if not all(c in table.columns for c in ACC):
        return segments_frame([])  # magnetometer-only: nothing rests in a way we can tell
    has_gyr = all(c in table.columns for c in GYR)
    cols = list(ACC) + (list(GYR) if has_gyr else [])
    values = table[cols].to_numpy(dtype=float)
    keep = np.flatnonzero(np.isfinite(values).all(axis=1))
    t = table[TIME].to_numpy(dtype=float)[keep]
    acc = values[keep, :3]
    gyr = values[keep, 3:] if has_gyr else None
    return to_table_rows(segment_poses(recording, t, acc, gyr, settings), keep)


def segment_dataset(
    tables: dict[str, pd.DataFrame],
    *,
    ratetable: dict | None = None,
    manual: list[dict] | None = None,
    window_s: float = 0.5,
    p_false: float = 1e-6,
    min_static_s: float = 1.0,
    rest_tol_dps: float = 2.0,
    scale_tol: float = 0.2,
    rest_drift_dps_per_s: float = 0.02,
    fallback: bool = False,
) -> pd.DataFrame:
    """The segments table of a dataset: automatic, or manual for recordings named in ``manual``.

    Parameters
    ----------
    tables : dict of str to DataFrame
        Ingested IMU recordings by name (``rotation3d``, ``cube``, ``ratetable``, ``static``).
    ratetable : dict, optional
        ``Dataset.ratetable``.
    manual : list of dict, optional
        ``Dataset.segments``: replaces the automatic segments of every recording it names.
    window_s, p_false, min_static_s, rest_tol_dps, scale_tol, rest_drift_dps_per_s
        See ``DetectorSettings``.
    fallback : bool
        For partial sessions: a recording whose protocol is not found (e.g. hand-held turns
        without the rests the rotation3d matching needs) keeps only its static poses, and the
        reason goes to ``attrs['notes']`` (recording -> message) instead of an error.

    Returns
    -------
    DataFrame
        Columns ``SEGMENT_COLUMNS``, recordings in protocol order, segments in time order.
        ``attrs['notes']`` (recording -> message): the fallbacks, and the rate-table runs found
        clipped at the sensor range or split by a disturbance (:func:`segment_ratetable`).
        ``attrs['held_by_hand']``: recordings whose holds came from the tremor-adaptive
        detector (:mod:`imucal.segments.holds`): held by hand, not at rest.
    """
    settings = DetectorSettings(
        window_s, p_false, min_static_s, rest_tol_dps, scale_tol, rest_drift_dps_per_s
    )
    manual = list(manual or [])
    unknown = sorted({e["recording"] for e in manual} - set(tables))
    if unknown:
        raise ValueError(
            f"manual segments name recording(s) {unknown}; the dataset has {sorted(tables)}"
        )
    frames, notes, held_by_hand = [], {}, []
    for name in [r for r in IMU_RECORDINGS if r in tables] + sorted(
        set(tables) - set(IMU_RECORDINGS)
    ):
        mine = [e for e in manual if e["recording"] == name]
        t = tables[name][TIME].to_numpy(dtype=float)
        if mine:
            frames.append(manual_segments(name, t, mine))
            continue
        try:
            frames.append(
                segment_recording(name, tables[name], ratetable=ratetable, settings=settings)
            )
            notes.update(frames[-1].attrs.get("notes", {}))
        except ValueError as err:
            if not fallback:
                raise
            notes[name] = f"{name}: automatic segmentation failed ({err}); static poses only"
            logger.warning(notes[name])
            frames.append(_segment_pose_recording(name, tables[name], settings))
        held_by_hand += frames[-1].attrs.get("held_by_hand", [])
        logger.info("%s: %d segments", name, len(frames[-1]))
        hint = short_rest_note(name, tables[name], frames[-1], settings) or orientation_note(
            name, tables[name], frames[-1], settings
        )
        if hint:
            notes[name] = f"{notes[name]}; {hint}" if name in notes else hint
            logger.warning(hint)
    out = pd.concat(frames, ignore_index=True) if frames else segments_frame([])
    out.attrs["notes"] = notes
    out.attrs["held_by_hand"] = held_by_hand
    return out


def short_rest_note(
    recording: str, table: pd.DataFrame, segments: pd.DataFrame, settings: DetectorSettings
) -> str:
    """For a recording without a rest: the still intervals too short to count, and the
    settings that would find them ('' when it has rests, or no such interval).

    Parameters
    ----------
    recording : str
    table : DataFrame
        Ingested recording.
    segments : DataFrame
        Its segments as found.
    settings : DetectorSettings
    """
    if segments["kind"].isin(["static", "position"]).any():
        return ""
    if not all(c in table.columns for c in (*ACC, *GYR)):
        return ""
    values = table[[*ACC, *GYR]].to_numpy(dtype=float)
    keep = np.isfinite(values).all(axis=1)
    t = table[TIME].to_numpy(dtype=float)[keep]
    short = find_short_rests(t, values[keep, :3], values[keep, 3:], settings)
    if not short:
        return ""
    lengths = np.array([b - a for a, b in short])
    shortest = float(np.floor(10 * lengths.min()) / 10)
    window = min(SHORT_WINDOW_S, settings.window_s)
    where = ", ".join(f"{a:.1f}-{b:.1f} s" for a, b in short[:8])
    return (
        f"{recording}: no rest of at least {settings.min_static_s:g} s was found, but "
        f"{len(short)} still interval(s) of {lengths.min():.2g}-{lengths.max():.2g} s were "
        f"({where}{', ...' if len(short) > 8 else ''}): the config's segmentation.min_static_s: "
        f"{max(shortest, 2 * window):g} and segmentation.window_s: {window:g} would look for them, "
        "or declare them under segments: in dataset.yaml (kind: static)"
    )


#: Recordings whose rests the cube fit (eq. 32) is run on.
CUBE_RECORDINGS = ("cube", "poses")
#: The shortest rests (``min_static_s``, s) tried when a recording's rests show too few
#: orientations for the cube fit, longest first; the windows are half as long.
SHORTER_STATIC_S = (0.8, 0.6, 0.5, 0.4, 0.3, 0.2)


def rest_coverage(table: pd.DataFrame, segments: pd.DataFrame) -> OrientationCoverage:
    """The distinct gravity directions of a recording's rests (static and position segments
    with enough accelerometer samples for the cube fit)."""
    means, counts = [], []
    acc = column_values(table, ACC)
    for a, b in segments.loc[segments["kind"].isin(["static", "position"])][
        ["start_index", "end_index"]
    ].itertuples(index=False):
        values = acc[int(a) : int(b)]
        values = values[np.isfinite(values).all(axis=1)]
        if len(values) >= MIN_SAMPLES_PER_POSITION:
            means.append(values.mean(axis=0))
            counts.append(len(values))
    return cube_coverage(np.array(means).reshape(-1, 3), np.array(counts, dtype=float))


def orientation_note(
    recording: str, table: pd.DataFrame, segments: pd.DataFrame, settings: DetectorSettings
) -> str:
    """For a recording of poses whose rests show too few orientations for the cube fit: the
    shorter ``min_static_s`` (and ``window_s``) under which its segmentation finds enough ('' when
    its rests suffice, or no setting of :data:`SHORTER_STATIC_S` helps).

    Each shorter setting is tried with the recording's own segmenter (:func:`segment_recording`);
    the one whose rests show the most distinct orientations is named (a hand-held module paused
    for less than a second has such rests only).

    Parameters
    ----------
    recording : str
    table : DataFrame
        Ingested recording.
    segments : DataFrame
        Its segments as found.
    settings : DetectorSettings
    """
    if recording not in CUBE_RECORDINGS or not all(c in table.columns for c in ACC):
        return ""
    found = rest_coverage(table, segments)
    if found.identifiable:
        return ""
    rests = int(segments["kind"].isin(["static", "position"]).sum())
    best = None  # the setting whose rests show the most orientations (the longer on a tie)
    for shorter in (s for s in SHORTER_STATIC_S if s < settings.min_static_s):
        window = min(settings.window_s, shorter / 2)
        trial = dataclasses.replace(settings, min_static_s=shorter, window_s=window)
        try:
            rows = segment_recording(recording, table, settings=trial)
        except ValueError:  # the segmenter's protocol is not found with these settings either
            continue
        coverage = rest_coverage(table, rows)
        if coverage.identifiable and (best is None or len(coverage.directions) > best[3]):
            best = (shorter, window, len(rows), len(coverage.directions))
    if best is None:
        return ""
    shorter, window, count, orientations = best
    return (
        f"{recording}: its {rests} rest(s) of at least {settings.min_static_s:g} s show gravity "
        f"in {len(found.directions)} distinct orientation(s), too few for the cube fit, but the "
        f"recording holds shorter still periods: with the config's segmentation.min_static_s: "
        f"{shorter:g} and segmentation.window_s: {window:g} the segmentation finds {count} rests "
        f"in {orientations} distinct orientations"
    )
