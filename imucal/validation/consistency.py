"""The shipped calibration's standard deviations checked against fits on independent parts of
its own data.

Every fit that ships states a standard deviation for each parameter, derived from a noise model.
Whether that model holds on a recording is checked here without any truth: the session is cut
into two parts that share no sample (:func:`imucal.validation.parts.split_session`), the same
chain calibrates each part, and per sensor the two part calibrations' difference is compared
with their stated standard deviations (:func:`compare_parts`). With honest standard deviations
each parameter's ``z = (a - b) / sqrt(sigma_a^2 + sigma_b^2)`` is standard normal, and a
group's RMS z (the difference whitened by the parts' covariance, :func:`group_rms_z`) is
``sqrt(chi2_r / r)`` for the group's rank ``r``. A model error beyond the noise (poses held by a
hand, a wandering bias) moves the parts apart by more. Where the stage left each pose out in
turn itself (the cube fit, the six faces), the held-out poses' z against their predicted
standard deviation are a second check of the same kind; since those share the fits on the other
poses, their RMS z inflates only where the largest is beyond chance too (Bonferroni,
:func:`loo_p_value`).

Where a group's RMS z exceeds :data:`RMS_Z_LIMIT`, the shipped calibration's standard deviations
of that group are multiplied by it (the measured excess, Birge's ratio as in the fits' own
goodness of fit) and the rule goes to its ``quality`` (:func:`ship`); where chance alone would
give that excess with a probability below :data:`SIGNIFICANT_P`, the fit also carries a warning,
which the report's summary shows. A fit whose held-out error is above :data:`HELDOUT_RATIO` of
the nominal calibration's (it barely beats nominal) carries a warning, and so does one that could
not be checked at all.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy import special  # chi-square tails without scipy.stats' import

from imucal.calibration import SensorCalibration
from imucal.columns import ACC, GYR, MAG, column_values
from imucal.uncertainty import GROUPS, PARAMETERS, std_of
from imucal.validation.parts import REST_KINDS, SCHEMES, TURN_STAGES, Part, split_session

#: Above this RMS z the stated standard deviations of a group are too small by that factor.
RMS_Z_LIMIT = 1.5
#: A held-out error above this fraction of the nominal calibration's barely beats nominal.
HELDOUT_RATIO = 0.5
#: The groups whose standard deviations are inflated by their own excess: the bias, and the
#: matrix (scale, non-orthogonality and misalignment derive from it and take its factor).
INFLATED = ("bias", "matrix")
#: Groups that derive from the matrix: one whose parts still differ beyond the limit after the
#: matrix's inflation is warned about (beyond chance, :data:`SIGNIFICANT_P`).
DERIVED = ("scale", "xi_rad", "alpha_rad")
#: An excess over the limit is warned about where chance alone gives it with a probability
#: below this (chi-square); below the limit nothing is. Three parameters exceed the limit by
#: chance with probability 0.08, and would warn about one honest sensor in ten.
SIGNIFICANT_P = 0.01
#: A relative eigenvalue below this is a direction the parts' covariance does not constrain.
RANK_TOLERANCE = 1e-9
#: Rests shorter than this many samples give no mean worth comparing.
MIN_REST_SAMPLES = 10
#: How the shipped standard deviations are scaled (each sensor's ``quality``).
RULE = (
    "fits on two independent parts of the data, and the stage's poses left out one at a time: "
    f"the standard deviations of a group whose RMS z exceeds {RMS_Z_LIMIT:g} times that RMS z "
    "(model error beyond the noise)"
)


@dataclass(frozen=True)
class PartFit:
    """What a chain shipped for one sensor: the stage and its calibration."""

    stage: str
    calibration: SensorCalibration


#: ``calibrate(tables, segments) -> {sensor: PartFit}``: the chain run on one part.
Calibrate = Callable[[Mapping[str, pd.DataFrame], pd.DataFrame], dict[str, PartFit]]


def sensor_covariance(cal: SensorCalibration) -> np.ndarray:
    """The 21 x 21 covariance of :data:`imucal.uncertainty.PARAMETERS` a calibration states:
    its ``covariance``, else the variances of its ``std`` (0 where it states none)."""
    if cal.covariance is not None:
        return np.asarray(cal.covariance, dtype=float)
    variance = np.zeros(len(PARAMETERS))
    for group, where in GROUPS.items():
        if group in cal.std:
            variance[where] = np.ravel(cal.std[group]) ** 2
    return np.diag(variance)


def sensor_values(cal: SensorCalibration) -> np.ndarray:
    """The 21 parameters of :data:`imucal.uncertainty.PARAMETERS`, shape (21,)."""
    d = cal.decomposition
    return np.concatenate([cal.bias, cal.matrix.ravel(), d.scale, d.xi_rad, d.alpha_rad])


def group_rms_z(difference: np.ndarray, covariance: np.ndarray) -> tuple[float, int]:
    """RMS of a difference whitened by its covariance, and the covariance's rank.

    ``difference^T C^+ difference`` over the directions ``C`` constrains (eigenvalues above
    :data:`RANK_TOLERANCE` of the largest) is chi-square with ``rank`` degrees of freedom when
    ``C`` is the difference's covariance; the RMS z is its square root over ``rank``.

    Returns
    -------
    rms_z : float
        NaN when the rank is 0 (nothing of the group is estimated).
    rank : int
    """
    c = (np.asarray(covariance, dtype=float) + np.asarray(covariance, dtype=float).T) / 2
    values, vectors = np.linalg.eigh(c)
    if values.size == 0 or values.max() <= 0:
        return float("nan"), 0
    keep = values > RANK_TOLERANCE * values.max()
    projected = vectors[:, keep].T @ np.asarray(difference, dtype=float)
    chi2 = float(np.sum(projected**2 / values[keep]))
    return float(np.sqrt(chi2 / keep.sum())), int(keep.sum())


def compare_parts(
    a: SensorCalibration, b: SensorCalibration, factors: Mapping[str, float] | None = None
) -> dict:
    """The two parts' calibrations of one sensor against their stated standard deviations.

    Parameters
    ----------
    a, b : SensorCalibration
        The same sensor's calibration from either part.
    factors : mapping, optional
        ``{'bias', 'matrix'}``: compare against the standard deviations times these
        (:func:`inflation_factors`, after the inflation); default 1.

    Returns
    -------
    dict
        ``groups``: per group of :data:`imucal.uncertainty.GROUPS` and ``all`` (bias and
        matrix) its ``rms_z`` (:func:`group_rms_z`, None when not estimated), ``rank`` and
        ``p_value`` (of ``rank rms_z^2`` under chi-square with ``rank`` dof); ``z``: per
        parameter ``(a - b) / sqrt(var_a + var_b)`` (None where neither states a std);
        ``max_abs_z`` and ``max_parameter``: the largest |z| and its parameter.
    """
    scale = _scales(factors or {"bias": 1.0, "matrix": 1.0})
    difference = sensor_values(a) - sensor_values(b)
    covariance = (sensor_covariance(a) + sensor_covariance(b)) * np.outer(scale, scale)
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    tiny = RANK_TOLERANCE * float(std.max())
    z = np.where(std > tiny, difference / np.where(std > tiny, std, 1.0), np.nan)
    groups = {}
    for name, where in {**GROUPS, "all": slice(0, 12)}.items():
        rms, rank = group_rms_z(difference[where], covariance[where, where])
        p = float(special.chdtrc(rank, rank * rms**2)) if rank else None
        groups[name] = {"rms_z": None if rank == 0 else rms, "rank": rank, "p_value": p}
    finite = np.isfinite(z)
    worst = int(np.nanargmax(np.abs(np.where(finite, z, np.nan)))) if finite.any() else None
    return {
        "groups": groups,
        "z": {p: (float(v) if np.isfinite(v) else None) for p, v in zip(PARAMETERS, z)},
        "max_abs_z": None if worst is None else float(abs(z[worst])),
        "max_parameter": None if worst is None else PARAMETERS[worst],
    }


def inflation_factors(groups: Mapping[str, Mapping]) -> dict[str, float]:
    """The factors of the bias's and of the matrix's standard deviations: each group's RMS z
    where it exceeds :data:`RMS_Z_LIMIT`, else 1."""
    out = {}
    for name in INFLATED:
        rms = groups[name]["rms_z"]
        out[name] = float(rms) if rms is not None and rms > RMS_Z_LIMIT else 1.0
    return out


def _scales(factors: Mapping[str, float]) -> np.ndarray:
    """Per parameter of :data:`imucal.uncertainty.PARAMETERS` the factor of its std: the
    bias's for the bias, the matrix's for the matrix and what derives from it."""
    scale = np.full(len(PARAMETERS), float(factors["matrix"]))
    scale[GROUPS["bias"]] = float(factors["bias"])
    return scale


def inflate(cal: SensorCalibration, factors: Mapping[str, float]) -> SensorCalibration:
    """The calibration with its bias's standard deviations times ``factors['bias']`` and its
    matrix's (and what derives from it) times ``factors['matrix']``: ``D C D`` with ``D``
    diagonal, so the covariance stays one. Its ``quality`` gains ``parts (bias)`` and
    ``parts (matrix)``: the variance factor (``inflation``, as the stages state theirs), the
    standard deviations' and the rule (:data:`RULE`)."""
    scale = _scales(factors)
    quality = dict(cal.quality)
    for group in INFLATED:
        f = float(factors[group])
        quality[f"parts ({group})"] = {"inflation": f**2, "std_factor": f, "rule": RULE}
    if cal.covariance is not None:
        covariance = np.asarray(cal.covariance, dtype=float) * np.outer(scale, scale)
        return replace(cal, covariance=covariance, std=std_of(covariance), quality=quality)
    std = {g: np.asarray(v, dtype=float) * scale[GROUPS[g]][0] for g, v in cal.std.items()}
    return replace(cal, std=std, quality=quality)


def rest_means(part: Part, sensor: str, recordings: Sequence[str] | None = None) -> np.ndarray:
    """Means of one sensor over a part's rests (at least :data:`MIN_REST_SAMPLES` finite
    samples each) in ``recordings`` (default all), shape (n, 3)."""
    tables, segments = part
    columns = {"acc": ACC, "gyr": GYR}[sensor]
    means = []
    for name, table in tables.items():
        if recordings is not None and name not in recordings:
            continue
        if not all(c in table.columns for c in columns):
            continue
        rows = segments[(segments["recording"] == name) & segments["kind"].isin(REST_KINDS)]
        for a, b in zip(rows["start_index"].astype(int), rows["end_index"].astype(int)):
            values = column_values(table, columns, slice(a, b))
            values = values[np.isfinite(values).all(axis=1)]
            if len(values) >= MIN_REST_SAMPLES:
                means.append(values.mean(axis=0))
    return np.array(means, dtype=float).reshape(-1, 3)


def heldout_errors(
    sensor: str,
    cal: SensorCalibration,
    part: Part,
    *,
    gravity_m_s2: float,
    field_norm: float,
    recordings: Sequence[str] | None = None,
) -> tuple[float, float] | None:
    """RMS error of a part's data under another part's calibration, and under the nominal one.

    The accelerometer: ``|mean| - g`` over the part's rests; the gyroscope: the rests' mean rate
    (the body is still); the magnetometer: ``|m| - field_norm`` over its samples. Only the
    ``recordings`` the stage fitted (default all).

    Returns
    -------
    (calibrated, nominal) : (float, float), or None
        The two RMS errors in the sensor's unit; None when the part has no such data.
    """
    tables, _ = part
    if sensor == "mag":
        chosen = [t for n, t in tables.items() if recordings is None or n in recordings]
        pieces = [column_values(t, MAG) for t in chosen if all(c in t for c in MAG)]
        values = np.vstack(pieces) if pieces else np.empty((0, 3))
        values = values[np.isfinite(values).all(axis=1)]
        if not len(values):
            return None
        after = np.linalg.norm(cal.apply(values, unit=cal.unit), axis=1) - field_norm
        before = np.linalg.norm(values, axis=1) - field_norm
    else:
        means = rest_means(part, sensor, recordings)
        if not len(means):
            return None
        calibrated = cal.apply(means, unit=cal.unit)
        if sensor == "acc":
            after = np.linalg.norm(calibrated, axis=1) - gravity_m_s2
            before = np.linalg.norm(means, axis=1) - gravity_m_s2
        else:
            after, before = calibrated.ravel(), means.ravel()
    return float(np.sqrt(np.mean(after**2))), float(np.sqrt(np.mean(before**2)))


def _pooled(pairs: list[tuple[float, float] | None]) -> dict | None:
    """The held-out errors of both directions (each part under the other's calibration)."""
    found = [p for p in pairs if p is not None]
    if not found:
        return None
    after = float(np.sqrt(np.mean([a**2 for a, _ in found])))
    before = float(np.sqrt(np.mean([b**2 for _, b in found])))
    return {
        "calibrated": after,
        "nominal": before,
        "ratio": after / before if before else None,
        "basis": "each part under the other part's calibration",
    }


def _parts_entry(scheme: str, fits: list[PartFit], heldout: dict | None) -> dict:
    """The comparison of the two parts' calibrations of one sensor, and the inflation it calls
    for: each of :data:`INFLATED` by its own excess, then both by what is left over bias and
    matrix together (their correlation: two groups each within the limit can differ beyond it
    together)."""
    a, b = fits[0].calibration, fits[1].calibration
    comparison = compare_parts(a, b)
    factors = inflation_factors(comparison["groups"])
    left = compare_parts(a, b, factors)["groups"]["all"]["rms_z"]
    if left is not None and left > RMS_Z_LIMIT:
        factors = {group: f * left for group, f in factors.items()}
    return {
        "scheme": scheme,
        **comparison,
        "inflation": factors,
        "groups_after": compare_parts(a, b, factors)["groups"],
        "heldout": heldout,
    }


def loo_p_value(loo: Mapping) -> float:
    """The probability that the largest |z| of ``loo['n']`` poses left out one at a time is as
    large by chance: Bonferroni's bound on the normal tail (the poses' held-out errors share the
    fits on the others, so they are not independent and their sum of squares is not
    chi-square)."""
    tail = float(special.ndtr(-float(loo["max_abs_z"])))
    return min(1.0, 2 * tail * int(loo["n"]))


def loo_significant(loo: Mapping) -> bool:
    """The poses left out call for an inflation: their RMS z is above :data:`RMS_Z_LIMIT` and
    the largest is beyond chance at :data:`SIGNIFICANT_P`."""
    return loo["rms_z"] > RMS_Z_LIMIT and loo_p_value(loo) < SIGNIFICANT_P


def _excess(stage: str, what: str, rms_z: float, rank: int, basis: str) -> str | None:
    """A warning for an RMS z above the limit that chance alone gives with probability below
    :data:`SIGNIFICANT_P` (chi-square with ``rank`` dof), else None."""
    p = float(special.chdtrc(rank, rank * rms_z**2))
    if rms_z <= RMS_Z_LIMIT or p >= SIGNIFICANT_P:
        return None
    return (
        f"{stage}: {what} {basis} by RMS z {rms_z:.2f} of the stated standard deviations "
        f"(limit {RMS_Z_LIMIT:g}; chi-square p = {p:.2g} on {rank} dof): model error beyond "
        "the noise"
    )


def _warnings(stage: str, unit: str, entry: Mapping) -> list[str]:
    """The warnings of one sensor's entry: an excess beyond chance (each group before the
    inflation, a derived group after it, the poses left out one at a time) with the inflation
    it caused, a held-out error that barely beats nominal, no check at all."""
    found = []
    parts, loo = entry.get("parts"), entry.get("leave_one_out")
    if parts:
        between = f"between two independent parts of the data ({parts['scheme']})"
        for group in (*INFLATED, "all"):
            g = parts["groups"][group]
            if g["rms_z"] is not None:
                name = (
                    "its bias and matrix together differ"
                    if group == "all"
                    else (f"its {group} differs")
                )
                found.append(_excess(stage, name, g["rms_z"], g["rank"], between))
        for group in DERIVED:
            g = parts["groups_after"][group]
            if g["rms_z"] is not None:
                what = f"after the inflation its {group} still differs"
                found.append(_excess(stage, what, g["rms_z"], g["rank"], between))
    if loo and loo_significant(loo):
        found.append(
            f"{stage}: its poses left out one at a time ({loo['basis']}) are off by RMS z "
            f"{loo['rms_z']:.2f} of their predicted standard deviations, the largest by "
            f"{loo['max_abs_z']:.1f} (limit {RMS_Z_LIMIT:g}; p = {loo_p_value(loo):.2g} for the "
            f"largest of {loo['n']}): model error beyond the noise"
        )
    out = [w for w in found if w]
    factors = entry["inflation"]
    if out and max(factors.values()) > 1.0:
        out.append(
            f"{stage}: its standard deviations are inflated x{factors['bias']:.2f} (bias) and "
            f"x{factors['matrix']:.2f} (matrix) by the measured excess"
        )
    # the stage's own poses left out one at a time are held out from a fit on nearly all the
    # data, like the shipped one; the parts' fits on half of it extrapolate further
    heldout = entry.get("own_heldout") or (parts or {}).get("heldout")
    if heldout:
        ratio = heldout.get("ratio")
        if ratio is not None and ratio > HELDOUT_RATIO:
            out.append(
                f"{stage}: held out ({heldout['basis']}) its error is "
                f"{heldout['calibrated']:.3g} {unit} against {heldout['nominal']:.3g} with the "
                f"nominal calibration ({ratio:.0%}, more than {HELDOUT_RATIO:.0%}): it barely "
                "beats the nominal calibration on data it was not fitted on"
            )
    if not parts and not loo:
        out.append(
            f"{stage}: its standard deviations could not be checked on independent parts of "
            f"the data ({entry['reason']})"
        )
    return out


def _part_pairs(
    sensor: str,
    fits: list[PartFit],
    parts: tuple[Part, Part],
    gravity_m_s2: float,
    field: float,
    recordings: Sequence[str] | None,
) -> dict | None:
    """Each part under the other part's calibration (:func:`heldout_errors`), pooled."""
    return _pooled(
        [
            heldout_errors(
                sensor,
                fits[1 - k].calibration,
                parts[k],
                gravity_m_s2=gravity_m_s2,
                field_norm=field,
                recordings=recordings,
            )
            for k in range(2)
        ]
    )


def check_parts(
    calibrate: Calibrate,
    tables: Mapping[str, pd.DataFrame],
    segments: pd.DataFrame,
    shipped: Mapping[str, PartFit],
    *,
    gravity_m_s2: float,
    field_norm: float,
    own: Mapping[str, Mapping] | None = None,
    sources: Mapping[str, Sequence[str]] | None = None,
) -> dict:
    """Each shipped sensor's calibration refitted on two independent parts, and the verdict.

    Parameters
    ----------
    calibrate : callable
        ``calibrate(tables, segments) -> {sensor: PartFit}``: the chain that made the shipped
        calibration, run on a part (the same functions, the same settings).
    tables, segments
        The session's ingested recordings and segments table.
    shipped : mapping of str to PartFit
        Per calibrated sensor the stage that shipped it and its calibration.
    gravity_m_s2, field_norm : float
        For the held-out errors (:func:`heldout_errors`).
    own : mapping, optional
        Sensor -> what the stage computed itself by leaving one pose out: ``leave_one_out``
        ``{'rms_z', 'max_abs_z', 'n', 'basis'}`` (the held-out poses' z against their
        predicted std) and
        ``heldout`` ``{'calibrated', 'nominal', 'ratio', 'basis'}`` (their RMS errors).
    sources : mapping, optional
        Sensor -> the recordings its stage fitted: the held-out errors use their data only
        (default every recording).

    Returns
    -------
    dict
        ``sensors``: sensor -> ``stage``; ``parts`` (when two parts shipped its stage: the
        ``scheme``, ``groups`` with RMS z, rank and p-value per group, ``z`` per parameter,
        ``max_abs_z``, ``max_parameter``, ``inflation``, ``groups_after``, ``heldout``) or
        ``reason`` (why not); ``leave_one_out`` and ``own_heldout`` where the stage has them;
        ``inflation`` (bias, matrix: the larger of the two checks' factors) and ``warnings``.
        ``limit_rms_z``, ``heldout_ratio``: the thresholds.
    """
    found: dict[str, dict] = {}
    tried: dict[str, list[str]] = {sensor: [] for sensor in shipped}
    for scheme in SCHEMES:
        todo = [
            sensor
            for sensor, fit in shipped.items()
            if sensor not in found and not (scheme == "within" and fit.stage in TURN_STAGES)
        ]
        if not todo:
            continue
        parts = split_session(tables, segments, scheme)
        fits = [calibrate(*part) for part in parts]
        for sensor in todo:
            stage = shipped[sensor].stage
            got = [f.get(sensor) for f in fits]
            if all(g is not None and g.stage == stage for g in got):
                used = (sources or {}).get(sensor)
                heldout = _part_pairs(sensor, got, parts, gravity_m_s2, field_norm, used)
                found[sensor] = _parts_entry(scheme, got, heldout)
                continue
            tried[sensor].append(
                f"{scheme}: "
                + "; ".join(
                    f"part {k + 1} shipped {g.stage if g else 'nothing'}"
                    for k, g in enumerate(got)
                    if g is None or g.stage != stage
                )
            )
    sensors = {
        sensor: _entry(fit, found.get(sensor), tried[sensor], (own or {}).get(sensor) or {})
        for sensor, fit in shipped.items()
    }
    return {"sensors": sensors, "limit_rms_z": RMS_Z_LIMIT, "heldout_ratio": HELDOUT_RATIO}


def _entry(fit: PartFit, parts: dict | None, tried: list[str], mine: Mapping) -> dict:
    """One sensor's entry of the check: its parts' comparison (or why there is none), what its
    stage left out itself, the inflation of both and the warnings."""
    entry: dict = {"stage": fit.stage}
    if parts is not None:
        entry["parts"] = parts
    else:
        if fit.stage in TURN_STAGES:
            tried = [*tried, "within: both parts would hold half of every turn"]
        entry["reason"] = "; ".join(tried)
    if mine.get("leave_one_out"):
        entry["leave_one_out"] = dict(mine["leave_one_out"])
    if mine.get("heldout"):
        entry["own_heldout"] = dict(mine["heldout"])
    factors = dict(parts["inflation"]) if parts else dict.fromkeys(INFLATED, 1.0)
    loo = entry.get("leave_one_out")
    if loo and loo_significant(loo):
        factors = {group: max(f, float(loo["rms_z"])) for group, f in factors.items()}
    entry["inflation"] = factors
    entry["warnings"] = _warnings(fit.stage, fit.calibration.unit, entry)
    return entry


def ship(calibration: Mapping, check: Mapping) -> dict:
    """The calibration a session ships: each sensor's standard deviations inflated by the
    check's factors (:func:`inflate`), the check's warnings under the sensor's ``warnings``.

    Parameters
    ----------
    calibration : mapping
        ``calibration.json`` as the chain made it (sensors as ``SensorCalibration`` dicts; any
        other key kept as it is).
    check : mapping
        :func:`check_parts`'s artifact.

    Returns
    -------
    dict
    """
    out = dict(calibration)
    for sensor, entry in check.get("sensors", {}).items():
        if sensor not in out:
            continue
        cal = inflate(SensorCalibration.from_dict(sensor, out[sensor]), entry["inflation"])
        out[sensor] = {**out[sensor], **cal.to_dict(), "warnings": list(entry["warnings"])}
    return out
