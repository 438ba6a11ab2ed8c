"""Temperature terms held out across static poses: each pose predicted from the others.

A recording of a motionless IMU left in a few static poses while its temperature sweeps (a
thermal chamber, a tag in a fridge) shows each sensor's drift with temperature, but every pose
adds its own constant: gravity along another axis, the g-sensitivity of the gyroscope, the
accelerometer's scale along that axis. So a pose's drift is predictable from the others only
up to its constant, and that is the test here: hold each pose out in turn, fit on the others,
predict the held-out pose's signal against its temperature, remove the constant, and compare
the residual RMS per pose, sensor and axis for

* ``none``: no temperature term (the held-out signal about its own mean);
* ``term``: this project's temperature term, a polynomial ``sum_k c_k dT^k`` per axis with one
  constant per fit pose as a nuisance (the constants absorb the orientation), its order
  ``0 .. max_order`` chosen per axis and held-out pose on the fit poses alone, each predicted
  from the others (:func:`nested_order`): an order has to beat no term on every fit pose, and
  among those that do, the one-standard-error rule of
  :func:`imucal.gap.temperature.select_model` picks, so an axis where no polynomial carries
  over from one fit pose to another gets no term;
* the peers (:mod:`imucal.terms.thermalpeers`): scikit-diveMove's ``IMUcalibrate`` (Luque),
  one line ``signal ~ temperature`` per period with its own intercept, each fit pose's model
  applied on its own (``imucal_1``, ``imucal_2``: the earlier and the later fit pose), and
  PX4's per-axis cubic in temperature (``cubic``) on the fit poses, each pose's median removed.

The held-out pose is compared on its samples within the fit poses' temperature span widened by
``margin_c`` (where the term calibrates; beyond it :class:`imucal.modelterms.TemperaturePolynomial`
refuses), every method on the same samples. The term is fitted to block means of ``block_s``
(the drift; the white noise averages out), the peers to the samples as they do; the
comparison is on every sample and on the block means. The residuals of a drift are
correlated over hours, so the uncertainty counts blocks of ``se_block_s`` as the independent
observations (an effective sample size of one per block): a standard error per RMS and a 95 %
interval per ratio, in two forms. Given the fits, the interval holds the held-out samples'
noise: it says whether these fitted models differ on this pose (``verdict_given_fits``). With
the fits' scatter (each fit block's influence on the fitted coefficients through the noise,
carried to the held-out residual) it says whether the two methods differ by more than their
fits scatter (``verdicts``). The term is better or worse than a peer where an interval excludes 1,
else within noise. The order's choice is taken as given.

A cell where the term is worse than no term held out, or resolvably worse than a peer (the
interval of term / peer with the fits' scatter above 1), is flagged and the term is not taken
there (:func:`imucal.terms.thermalship.judge_cell`); an axis ships its term, fitted on every
pose, only where every held-out pose takes it (``shipped``), and
:func:`imucal.terms.thermalship.with_shipped_terms` puts it into a session's calibration. The
poses' samples, the term's fit and the choice of its order are in
:mod:`imucal.terms.poseseries`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from imucal.columns import (
    AXES,
    POSE_KINDS,
    SENSOR_COLUMNS,
    SENSORS,
    SI_UNITS,
    TEMPERATURE_COLUMNS,
)
from imucal.segments.table import rows_of
from imucal.terms.blockspread import (
    block_index,
    block_sums,
    influence,
    spread,
    verdict_of,
)
from imucal.terms.poseseries import (
    PoseSeries,
    centred,
    choose_order,
    heldout_residual,
    inside_span,
    nested_order,
    pose_blocks,
    pose_series,
    powers,
    predict_term,
    rms,
    temperature_span,
    term_design,
)
from imucal.terms.thermalpeers import (
    PeerFit,
    median_filtered,
    peer_label,
    peer_names,
    per_period_line,
    px4_cubic,
    smoothed,
)
from imucal.terms.thermalship import judge_cell

#: The fewest poses a hold-out needs: one held out, at least two to fit on.
MIN_POSES = 3


def hold_out_poses(
    poses: Sequence[PoseSeries],
    *,
    block_s: float,
    max_order: int,
    margin_c: float,
    se_block_s: float,
) -> dict:
    """Held-out residual RMS per pose x sensor x axis: no term, the project's term, the peers.

    Parameters
    ----------
    poses : sequence of PoseSeries
        At least :data:`MIN_POSES` poses with samples, the same sensors each, in time order.
    block_s : float
        Block length (s) of the term's fit (block means) and of the block comparison.
    max_order : int
        Highest polynomial order tried (>= 1).
    margin_c : float
        How far beyond the fit poses' temperature span (K) a held-out sample is compared.
    se_block_s : float
        Block length (s) of the standard errors (the order's, the RMS's and the ratios'):
        longer than the correlation of the residuals.

    Returns
    -------
    dict
        ``methods``: the compared methods (``none``, ``term``, then the peers of
        :func:`imucal.terms.thermalpeers.peer_names`: ``imucal_1`` .. one per fit pose in
        time order, and ``cubic``) with their labels. ``cells``: one per held-out pose, sensor and axis, with
        ``held_out``, ``sensor``, ``axis``, ``unit``, ``samples`` (compared), ``fraction`` (of
        the pose's samples within the span), ``rms_<method>`` (samples, constant removed) and
        its standard error ``rms_<method>_se``, the ratio of each method to none
        ``<method>_ratio`` and of the term to each peer ``term_vs_<peer>``, each with its 95 %
        interval with the fits' scatter (``..._ci95``) and given the fits
        (``..._ci95_given_fits``), ``verdicts`` (per peer, the term ``better``, ``worse`` or
        ``within noise`` with the fits' scatter) and ``verdicts_given_fits``, ``flags``,
        ``flagged`` and ``taken`` (:func:`~imucal.terms.thermalship.judge_cell`), ``clusters``
        and ``fit_clusters`` (:func:`~imucal.terms.blockspread.spread`), the RMS of the block
        means (``blocks_<method>``), ``order`` (chosen on the fit poses alone,
        :func:`nested_order`), ``inner_rms``, ``coef`` (``c_1 .. c_order``, unit per K^k),
        ``reference_c`` and ``peer_coef`` (per peer, its coefficients and reference).
        ``orders``: per sensor and axis the order of each held-out pose and ``outer_rms``, the
        RMS over all held-out samples of every order. ``summary``: per sensor and axis, the
        same figures over all held-out samples (the blocks of all poses as clusters), with its
        flags. ``shipped``: per sensor and axis the term the hold-out takes, fitted on every
        pose (:func:`_shipped`). ``warnings``: poses with fewer than three blocks of
        ``se_block_s`` (:func:`_short_poses`) and the flagged cells. ``poses``: label, samples, temperature span.

    Raises
    ------
    ValueError
        Fewer than :data:`MIN_POSES` poses with samples, or ``max_order < 1``.

    Notes
    -----
    The order is chosen in a nested way: for each held-out pose on the two (or more) fit
    poses alone, each predicted from the others, so the held-out residual the table reports
    played no part in it. An information criterion on the fit poses' residuals would need a
    noise model for a drift correlated over hours; the inner hold-out asks the question the
    term has to answer (does the polynomial carry over to a pose it has not seen) without one.
    """
    poses = [p for p in poses if len(p.t_s)]
    if len(poses) < MIN_POSES:
        raise ValueError(
            f"{len(poses)} static pose(s) with samples; holding one out needs at least {MIN_POSES}"
        )
    if max_order < 1:
        raise ValueError(f"max_order must be >= 1, got {max_order}")
    if not float(se_block_s / block_s).is_integer():
        raise ValueError(
            f"se_block_s ({se_block_s} s) must be a whole number of block_s ({block_s} s): "
            "each block of the term's fit belongs to one block of the standard errors"
        )
    sensors = list(poses[0].values)
    blocks = [pose_blocks(p, block_s) for p in poses]
    # every se_block_s block of every pose, numbered across the session (the fits' clusters)
    first = np.cumsum([0] + [_block_count(p, se_block_s) for p in poses])
    labels = [first[k] + block_index(p.t_s, se_block_s, p.t_s[0]) for k, p in enumerate(poses)]
    filtered = {
        "smoothed": [{s: smoothed(p.values[s]) for s in sensors} for p in poses],
        "median": [{s: median_filtered(p.values[s]) for s in sensors} for p in poses],
    }
    folds = []
    for h in range(len(poses)):
        fit = [p for p in range(len(poses)) if p != h]
        lo, hi = temperature_span([poses[p].temp_c for p in fit], margin_c)
        folds.append({
            "fit": fit, "inside": inside_span(poses, fit, h, margin_c), "first": first, "held": h,
            "block_in": (blocks[h][0] >= lo) & (blocks[h][0] <= hi), "se_block_s": se_block_s,
        })  # fmt: skip
    cells, orders, summary, shipped = [], [], [], []
    for s in sensors:
        for j, axis in enumerate(AXES):
            outer = {k: [] for k in range(max_order + 1)}
            group = []
            for h, (held, fold) in enumerate(zip(poses, folds)):
                order, inner = nested_order(
                    poses, blocks, fold["fit"], s, j, max_order=max_order, margin_c=margin_c,
                    se_block_s=se_block_s,
                )  # fmt: skip
                inside = fold["inside"]
                for k in outer:
                    r = heldout_residual(
                        poses, blocks, fold["fit"], held, inside, s, j, k, margin_c
                    )[0]
                    outer[k].append(block_sums(centred(r) ** 2, held.t_s[inside], se_block_s))
                fitted = heldout_residual(
                    poses, blocks, fold["fit"], held, inside, s, j, order, margin_c
                )
                term_influence = _term_influence(blocks, fold, s, j, order, fitted[2])
                peers = _peer_fits(poses, filtered, labels, fold, s, j)
                cell, parts = _cell(held, blocks[h], fold, s, j, order, fitted, term_influence,
                                    peers)  # fmt: skip
                cells.append({**cell, "inner_rms": inner})
                group.append((cell, parts))
            chosen, outer_rms = choose_order(outer)
            orders.append({
                "sensor": s, "axis": axis,
                "by_pose": {c["held_out"]: c["order"] for c, _ in group},
                "outer_rms": outer_rms, "outer_order": chosen,
            })  # fmt: skip
            summary.append(_summary(group))
            shipped.append(
                _shipped(poses, blocks, first, se_block_s, s, j, group, chosen, margin_c)
            )
    return {
        "methods": {
            "none": "no temperature term",
            "term": "this project's temperature term",
            **{m: peer_label(m) for m in peer_names(len(poses) - 1)},
        },
        "poses": [
            {
                "label": p.label,
                "samples": len(p.t_s),
                "temp_span_c": [float(p.temp_c.min()), float(p.temp_c.max())],
            }
            for p in poses
        ],  # fmt: skip
        "orders": orders,
        "cells": cells,
        "summary": summary,
        "shipped": shipped,
        "warnings": _short_poses(poses, se_block_s) + _flag_warnings(cells + summary),
    }


def _flag_warnings(cells: Sequence[Mapping]) -> list[str]:
    """One warning per flagged cell: where the term is not taken, and why."""
    return [
        f"{c.get('held_out', 'all poses')} {c['sensor']} {c['axis']}: {'; '.join(c['flags'])}; "
        "the term is not taken there"
        for c in cells
        if c["flags"]
    ]


def _short_poses(poses: Sequence[PoseSeries], se_block_s: float) -> list[str]:
    """A warning per pose with fewer than three blocks of ``se_block_s``: its standard errors
    rest on one degree of freedom or none (one block: no spread, so no order can be admitted
    on it and its intervals are undefined)."""
    out = []
    for p in poses:
        span_s, blocks = float(p.t_s[-1] - p.t_s[0]), _block_count(p, se_block_s)
        if blocks < 3:
            consequence = (
                "no spread over blocks: no order can be admitted on it and its intervals are "
                "undefined"
                if blocks == 1
                else "its standard errors rest on one degree of freedom"
            )
            out.append(
                f"pose {p.label!r} spans {span_s:.0f} s, {blocks} block(s) of se_block_s "
                f"({se_block_s:.0f} s): {consequence}; set temperature_holdout.se_block_s to "
                "the residuals' correlation time, at most a third of the shortest pose"
            )
    return out


def _block_count(pose: PoseSeries, se_block_s: float) -> int:
    """The blocks of ``se_block_s`` a pose's samples fall in, from its first sample."""
    return int(block_index(pose.t_s[-1:], se_block_s, pose.t_s[0])[0]) + 1


def _term_influence(
    blocks: Sequence[tuple], fold: Mapping, sensor: str, j: int, order: int, reference_c: float
) -> np.ndarray:
    """Each block's influence on the term's coefficients ``c_1 .. c_order`` fitted on the
    fold's fit poses (:func:`~imucal.terms.blockspread.influence`, the blocks numbered across
    the session), shape (C, order)."""
    fit = fold["fit"]
    temps = [blocks[p][0] for p in fit]
    design = term_design(temps, order, reference_c)
    y = np.concatenate([blocks[p][1][sensor][:, j] for p in fit])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    labels = np.concatenate(
        [fold["first"][p] + block_index(blocks[p][2], fold["se_block_s"], 0.0) for p in fit]
    )
    return influence(design, y - design @ coef, labels, fold["first"][-1])[:, len(fit) :]


def _peer_fits(poses, filtered, labels, fold, sensor: str, j: int) -> dict:
    """The peers' models of one axis fitted on the fold's fit poses: ``imucal_k`` on fit pose
    k alone (smoothed), ``cubic`` on all of them (median-filtered)."""
    fit, n_clusters = fold["fit"], int(fold["first"][-1])
    out = {
        f"imucal_{k}": per_period_line(
            poses[p].temp_c, filtered["smoothed"][p][sensor][:, j], labels[p], n_clusters
        )
        for k, p in enumerate(fit, 1)
    }
    out["cubic"] = px4_cubic(
        [poses[p].temp_c for p in fit],
        [filtered["median"][p][sensor][:, j] for p in fit],
        [labels[p] for p in fit],
        n_clusters,
    )
    return out


def _cell(
    held: PoseSeries,
    block: tuple,
    fold: Mapping,
    sensor: str,
    j: int,
    order: int,
    fitted: tuple,
    term_influence: np.ndarray,
    peers: Mapping[str, PeerFit],
) -> tuple[dict, tuple]:
    """One held-out pose, sensor and axis: every method's residual RMS with their spread,
    the flags, and what :func:`~imucal.terms.blockspread.spread` takes (per method the block
    sums of the squared residuals and the samples per block, the blocks' indices, the fits'
    influence on the sums of squares)."""
    residual, coef, reference_c = fitted
    inside = fold["inside"]
    y, temp, t_s = held.values[sensor][inside, j], held.temp_c[inside], held.t_s[inside]
    block_t, block_v, _ = block
    yb, tb = block_v[sensor][fold["block_in"], j], block_t[fold["block_in"]]
    r = {"none": centred(y), "term": centred(residual)}
    designs = {"term": powers(temp - reference_c, order)}
    coefficients = {"term": term_influence}
    blocks_rms = {"none": rms(centred(yb)),
                  "term": rms(centred(yb - predict_term(coef, tb, reference_c)))}  # fmt: skip
    for name, peer in peers.items():
        r[name] = centred(y - peer.predict(temp))
        designs[name], coefficients[name] = peer.powers(temp), peer.influence
        blocks_rms[name] = rms(centred(yb - peer.predict(tb)))
    se_block_s, origin = fold["se_block_s"], held.t_s[0]
    squares = {m: block_sums(v**2, t_s, se_block_s, origin) for m, v in r.items()}
    ids = fold["first"][fold["held"]] + np.unique(block_index(t_s, se_block_s, origin))
    # d(sum of squares) / d(coefficient) on the held-out samples, times each block's influence
    fit_influence = {"none": np.zeros(len(term_influence))}
    for m, x in designs.items():
        fit_influence[m] = coefficients[m] @ (-2.0 * r[m] @ (x - x.mean(axis=0)))
    stats = spread(squares, ids, fit_influence, _comparisons(peers))
    cell = {
        "held_out": held.label, "sensor": sensor, "axis": AXES[j], "unit": SI_UNITS[sensor],
        "samples": int(inside.sum()), "fraction": float(inside.mean()),
        **{f"rms_{m}": rms(v) for m, v in r.items()}, **stats,
        **_verdicts(stats, peers), "blocks": int(fold["block_in"].sum()),
        **{f"blocks_{m}": v for m, v in blocks_rms.items()},
        "order": order, "coef": coef.tolist(), "reference_c": reference_c,
        "peer_coef": {m: {"coef": p.coef.tolist(), "reference_c": p.reference_c}
                      for m, p in peers.items()},
    }  # fmt: skip
    return {**cell, **judge_cell(cell, list(peers), order > 0)}, (squares, ids, fit_influence)


def _comparisons(peers: Sequence[str]) -> list[tuple[str, str, str]]:
    """The ratios of a cell: each method to none, the term to each peer."""
    methods = ["term", *peers]
    return [(f"{m}_ratio", m, "none") for m in methods] + [
        (f"term_vs_{p}", "term", p) for p in peers
    ]


def _verdicts(stats: Mapping, peers: Sequence[str]) -> dict:
    return {
        "verdicts": {p: verdict_of(stats[f"term_vs_{p}_ci95"]) for p in peers},
        "verdicts_given_fits": {
            p: verdict_of(stats[f"term_vs_{p}_ci95_given_fits"]) for p in peers
        },
    }


def _summary(group: Sequence[tuple[Mapping, tuple]]) -> dict:
    """One sensor and axis over every held-out sample of its poses: each method's RMS, its
    standard error and the ratios' intervals (the blocks of every pose as clusters, a pose's
    blocks both held out and, for the other poses' predictions, fitted on), with its flags."""
    cells = [c for c, _ in group]
    methods = list(group[0][1][0])
    peers = [m for m in methods if m not in ("none", "term")]
    squares = {
        m: tuple(np.concatenate([sq[m][i] for _, (sq, _, _) in group]) for i in (0, 1))
        for m in methods
    }
    ids = np.concatenate([i for _, (_, i, _) in group])
    fit_influence = {m: sum(f[m] for _, (_, _, f) in group) for m in methods}
    n = squares["none"][1].sum()
    stats = spread(squares, ids, fit_influence, _comparisons(peers))
    out = {
        "sensor": cells[0]["sensor"], "axis": cells[0]["axis"], "unit": cells[0]["unit"],
        **{f"rms_{m}": float(np.sqrt(v[0].sum() / n)) if n else float("nan")
           for m, v in squares.items()},
        **stats, **_verdicts(stats, peers), "orders": [c["order"] for c in cells],
    }  # fmt: skip
    judged = judge_cell(out, peers, any(c["order"] for c in cells))
    return {**out, **judged, "taken": all(c["taken"] for c in cells) and judged["taken"]}


def _shipped(poses, blocks, first, se_block_s: float, sensor: str, j: int, group, order: int,
             margin_c: float) -> dict:  # fmt: skip
    """The term of one axis that ships, fitted on the block means of every pose.

    It ships where the hold-out takes it in every held-out pose (:func:`judge_cell`: order
    >= 1, not worse than no term, not resolvably worse than a peer) and over all of them, at
    the order :func:`choose_order` picks with every pose predicted from the others. The
    coefficients' covariance is cluster-robust (every block of ``se_block_s`` one cluster,
    with the factor C / (C - 1)); ``mean_drift`` is the drift's mean over the poses' samples
    (how far the poses' mean level, as a bias fitted on them holds it, lies from the level at
    ``reference_c``).
    """
    cells = [c for c, _ in group]
    out = {"sensor": sensor, "axis": AXES[j]}
    refused = [f"{c['held_out']}: " + ("; ".join(c["flags"]) or "no order carries over")
               for c in cells if not c["taken"]]  # fmt: skip
    if refused or order == 0:
        reason = "; ".join(refused) or "no order carries over to every pose"
        return {**out, "taken": False, "reason": reason}
    temps = [b[0] for b in blocks]
    lo, hi = temperature_span([p.temp_c for p in poses], 0.0)
    reference_c = round(0.5 * (lo + hi), 2)
    design = term_design(temps, order, reference_c)
    y = np.concatenate([b[1][sensor][:, j] for b in blocks])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    block_labels = np.concatenate(
        [first[k] + block_index(b[2], se_block_s, 0.0) for k, b in enumerate(blocks)]
    )
    n_clusters = int(first[-1])
    spread_of = influence(design, y - design @ coef, block_labels, n_clusters)[:, len(poses) :]
    covariance = n_clusters / (n_clusters - 1) * spread_of.T @ spread_of
    all_temp = np.concatenate([p.temp_c for p in poses])
    return {
        **out, "taken": True, "reason": "taken in every held-out pose", "order": order,
        "coef": coef[len(poses) :].tolist(), "coef_std": np.sqrt(np.diag(covariance)).tolist(),
        "covariance": covariance.tolist(), "reference_c": reference_c, "span_c": [lo, hi],
        "margin_c": margin_c, "unit": SI_UNITS[sensor],
        "mean_drift": float(np.mean(predict_term(coef[len(poses) :], all_temp, reference_c))),
    }  # fmt: skip


def holdout_recording(dataset) -> str | None:
    """The recording of a dataset with declared static poses and a temperature channel.

    Parameters
    ----------
    dataset : imucal.io.dataset.Dataset

    Returns
    -------
    str or None
        The first recording (in ``dataset.yaml`` order) whose reader declaration maps a
        temperature column (:data:`imucal.columns.TEMPERATURE_COLUMNS`) and for which
        ``segments:`` declares at least :data:`MIN_POSES` static poses; None when there is none
        (automatic segments are known only after the segmentation has run).
    """
    from imucal.io.readers import declared_entries

    for name, declaration in dataset.readers.items():
        targets = {t for e in declared_entries(declaration) for t in (e.get("columns") or {})}
        poses = [s for s in dataset.segments if s["recording"] == name and s["kind"] in POSE_KINDS]
        if targets & set(TEMPERATURE_COLUMNS) and len(poses) >= MIN_POSES:
            return name
    return None


def hold_out_recording(
    table: pd.DataFrame,
    segments: pd.DataFrame,
    *,
    recording: str,
    block_s: float,
    settle_s: float,
    max_order: int,
    margin_c: float,
    se_block_s: float,
) -> dict:
    """:func:`hold_out_poses` on the static poses of one ingested recording, with its settings.

    Parameters
    ----------
    table : DataFrame
        The ingested recording (SI units, a temperature column).
    segments : DataFrame
        The session's segments table; the recording's ``position`` and ``static`` rows are the
        poses.
    recording : str
    block_s, settle_s, max_order, margin_c, se_block_s
        See :func:`pose_series` and :func:`hold_out_poses`.

    Returns
    -------
    dict
        The result of :func:`hold_out_poses` with ``recording``, ``sensors`` and ``settings``.
    """
    sensors = [s for s in SENSORS if all(c in table.columns for c in SENSOR_COLUMNS[s])]
    rows = rows_of(segments, recording, *POSE_KINDS)
    poses = pose_series(table, rows, settle_s=settle_s, sensors=sensors)
    settings = {"block_s": block_s, "settle_s": settle_s, "max_order": max_order,
                "margin_c": margin_c, "se_block_s": se_block_s}  # fmt: skip
    result = hold_out_poses(poses, **{k: v for k, v in settings.items() if k != "settle_s"})
    return {"recording": recording, "sensors": sensors, "settings": settings, **result}
