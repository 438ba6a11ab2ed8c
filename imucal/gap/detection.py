"""Detection limits of the diagnosis: how small an effect it still names, from a sweep.

Every effect of the diagnosis's library is rendered alone at magnitudes on a geometric grid of
factors of its realistic default (:meth:`Effect.scaled`), each on several seeds. The sessions
are rendered like the blind check's (:func:`imucal.gap.blind.render_blind_session`, the answer
key sealed apart, names ``d000``, ``d001``, ... that do not reveal the effect), diagnosed by
:func:`imucal.gap.checks.diagnose_folder` and scored by :func:`score_detection`: per effect and
factor the fraction of sessions in which the diagnosis names the effect
(:func:`imucal.gap.stress.is_named`), and per effect the **detection limit**, the smallest
magnitude named in at least a given fraction of the sessions at it and at every larger one.
docs/gap.md ("Detection limits") describes the sweep and its cost.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy import stats

from imucal.gap.blind import effect_estimate
from imucal.gap.library import scope_library
from imucal.gap.stress import is_named
from imucal.sim import SENSITIVITY
from imucal.sim.effects import CANONICAL, Effect, make_effect, stream_rng

#: Effects whose headline magnitude falls as the effect gets harsher: ``saturation``'s is the
#: gyroscope's clip level, and a lower range clips more.
HARSHER_WHEN_SMALLER = ("saturation",)


def library_effects(effects: Sequence[str] | None = None) -> list[str]:
    """The effects to sweep: ``effects``, or every effect the full protocol's diagnosis
    estimates (:func:`imucal.gap.library.scope_library`), in the simulator's order
    (:data:`imucal.sim.effects.CANONICAL`, then the others in the specs' order).

    Raises
    ------
    ValueError
        If an effect is not in the diagnosis's library.
    """
    protocol = scope_library("protocol")
    if effects is None:
        first = [e for e in CANONICAL if e in protocol]
        return first + [e for e in protocol if e not in first]
    unknown = sorted(set(effects) - set(protocol))
    if unknown:
        raise ValueError(f"effects {unknown} are not in the diagnosis's library {sorted(protocol)}")
    return list(effects)


def magnitude_si(effect: Effect) -> dict:
    """The headline magnitude of an effect in SI, with its unit.

    :meth:`Effect.magnitude`, except for ``saturation``, whose magnitude is a count: its gyro
    clip level times the simulator's gyro sensitivity (:data:`imucal.sim.SENSITIVITY`, the one
    the sessions are rendered with), in rad/s.

    Returns
    -------
    dict
        ``value`` and ``unit``.
    """
    m = effect.magnitude()
    if effect.name == "saturation":
        return {"value": m.value * SENSITIVITY["gyr"], "unit": "rad/s"}
    return {"value": m.value, "unit": m.unit}


def detection_levels(
    factors: Sequence[float], effects: Sequence[str] | None = None
) -> dict[str, dict[float, Effect | str]]:
    """Each effect at each factor of its realistic default magnitude.

    What the factor scales, per effect (:meth:`Effect.magnitude` is the headline number):

    * most effects: every parameter of ``scalable``, so the magnitude is ``factor`` times the
      realistic one (e.g. ``lever_arm`` |r| in m, ``packet_loss`` the lost fraction,
      ``time_offset`` the offset in s with the clock drift, ``earth_rotation`` the rate in
      rad/s, although the Earth's is fixed: a factor stands for a rest too short or a gyro too
      noisy to see it);
    * ``mag_latency``: the mean age of the field, ``delay_s + 1 / (2 rate_hz)`` in s, scales
      exactly: ``delay_s`` times the factor, the magnetometer's rate divided by it;
    * ``saturation``: the gyroscope's clip level in counts (the accelerometer's kept at 2 g),
      rounded to a count, so the effect gets *harsher* as the factor falls
      (:data:`HARSHER_WHEN_SMALLER`); a level above the int16 range (32767 counts) is no
      effect and cannot be rendered.

    Parameters
    ----------
    factors : sequence of float
        Factors of the realistic magnitude, each > 0.
    effects : sequence of str, optional
        See :func:`library_effects`.

    Returns
    -------
    dict
        Effect -> factor -> the scaled :class:`Effect`, or the reason (str) it cannot be
        rendered at that factor.

    Raises
    ------
    ValueError
        If ``factors`` is empty, has duplicates or a factor that is not > 0.
    """
    factors = [float(f) for f in factors]
    if not factors or len(set(factors)) != len(factors) or min(factors) <= 0:
        raise ValueError(f"factors must be distinct and > 0, got {factors}")
    out = {}
    for name in library_effects(effects):
        base, levels = make_effect(name), {}
        for f in sorted(factors):
            try:
                levels[f] = base.scaled(f)
            except ValueError as err:
                levels[f] = str(err)
        out[name] = levels
    return out


def detection_plan(
    seed: int,
    factors: Sequence[float],
    seeds_per_level: int,
    effects: Sequence[str] | None = None,
    n_clean: int = 0,
) -> list[dict]:
    """The detection sweep's sessions, deterministic from ``seed``.

    Parameters
    ----------
    seed : int
    factors : sequence of float
        Factors of each effect's realistic magnitude (:func:`detection_levels`).
    seeds_per_level : int
        Sessions per effect and factor (>= 1). The ``j``-th session of an effect has the same
        seed (truth, noise) at every factor (common random numbers: the rate of an effect
        changes with its factor, not with a new draw of truths).
    effects : sequence of str, optional
        See :func:`library_effects`.
    n_clean : int
        Sessions without any effect (``effect`` None, no magnitude), shuffled among the others:
        the false-positive rate on clean sessions.

    Returns
    -------
    list of dict
        In name order (``d000``, ``d001``, ..., shuffled by the seed): ``name``, ``seed``,
        ``effect``, ``factor``, ``magnitude`` (:meth:`Effect.magnitude` of the scaled effect:
        ``value``, ``unit``, ``meaning``), ``magnitude_si`` (:func:`magnitude_si`),
        ``effects`` (the simulator effect with its parameters), ``exclude`` (empty),
        ``description``. Levels that cannot be rendered (:func:`detection_levels`) have no
        sessions.

    Raises
    ------
    ValueError
        If ``seeds_per_level`` < 1, or as :func:`detection_levels`.
    """
    if seeds_per_level < 1 or n_clean < 0:
        raise ValueError(
            f"expected seeds_per_level >= 1 and n_clean >= 0, got {seeds_per_level}, {n_clean}"
        )
    specs = []
    for name, levels in detection_levels(factors, effects).items():
        seeds = [
            int(stream_rng(seed, f"detection/{name}/{j}").integers(2**31))
            for j in range(seeds_per_level)
        ]
        for factor, effect in levels.items():
            if isinstance(effect, str):
                continue
            m = effect.magnitude()
            for session_seed in seeds:
                specs.append({
                    "seed": session_seed, "effect": name, "factor": factor,
                    "magnitude": {"value": m.value, "unit": m.unit, "meaning": m.meaning},
                    "magnitude_si": magnitude_si(effect),
                    "effects": [{"effect": name, "params": effect.params()}], "exclude": [],
                    "description": "detection session (answer key sealed)",
                })  # fmt: skip
    for j in range(n_clean):
        specs.append({
            "seed": int(stream_rng(seed, f"detection/clean/{j}").integers(2**31)),
            "effect": None, "factor": None, "magnitude": None, "magnitude_si": None,
            "effects": [], "exclude": [], "description": "detection session (answer key sealed)",
        })  # fmt: skip
    order = stream_rng(seed, "detection/plan").permutation(len(specs))
    width = max(3, len(str(len(specs) - 1)))
    return [{"name": f"d{i:0{width}d}", **specs[j]} for i, j in enumerate(order)]


def named_needed(n: int, rate: float) -> int:
    """Sessions of ``n`` that must name an effect for a detection rate >= ``rate``:
    ``ceil(rate n)``."""
    return math.ceil(round(rate * n, 9))


def clopper_pearson_lower(k: int, n: int, confidence: float) -> float:
    """One-sided Clopper-Pearson lower bound of a rate from ``k`` successes of ``n``.

    The rate ``p`` with ``P(X >= k | p) = 1 - confidence``, ``X ~ Binomial(n, p)``: the
    ``1 - confidence`` quantile of ``Beta(k, n - k + 1)``; 0 for ``k = 0``. For ``k = n`` it is
    ``(1 - confidence)^(1/n)`` (10 of 10 at 95 %: 0.741).

    Raises
    ------
    ValueError
        If not ``0 <= k <= n``, ``n >= 1`` and ``0 < confidence < 1``.
    """
    if not (n >= 1 and 0 <= k <= n and 0 < confidence < 1):
        raise ValueError(
            f"expected 0 <= k <= n, n >= 1, 0 < confidence < 1; got {k}, {n}, {confidence}"
        )
    return 0.0 if k == 0 else float(stats.beta.ppf(1 - confidence, k, n - k + 1))


def _median(values: list) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.median(values)) if values else None


def _level(rows: list[dict], key: Mapping, rate: float, confidence: float) -> dict:
    """The score of one effect at one factor, from its sessions' rows and one sealed key."""
    n, k = len(rows), sum(r["named"] for r in rows)
    named = [r for r in rows if r["named"]]
    needed = named_needed(n, rate)
    return {
        "factor": key["spec"]["factor"], "magnitude": key["magnitude"]["value"],
        "unit": key["magnitude"]["unit"], "magnitude_si": key["spec"]["magnitude_si"]["value"],
        "unit_si": key["spec"]["magnitude_si"]["unit"], "n": n, "named": k, "needed": needed,
        "rate": k / n, "cp_lower": clopper_pearson_lower(k, n, confidence),
        "detected": k >= needed, "crashed": sum(r["crashed"] for r in rows),
        "other_explained": sum(bool(r["other_explained"]) for r in rows),
        "noted_only": sum(not r["named"] and r["effect"] in r["noted"] for r in rows),
        "other_noted": sum(bool(r["other_noted"]) for r in rows),
        "median_heldout_shrink": _median([r["heldout_shrink"] for r in named]),
        "median_magnitude_rel_error": _median([r["magnitude_rel_error"] for r in named]),
    }  # fmt: skip


def detection_limit(effect: str, levels: Sequence[Mapping]) -> dict | None:
    """The least harsh level named at the required rate, together with every harsher level.

    Parameters
    ----------
    effect : str
    levels : sequence of dict
        The effect's levels (``factor``, ``detected``, ...), any order.

    Returns
    -------
    dict or None
        The level (for most effects the smallest factor, for :data:`HARSHER_WHEN_SMALLER`
        the largest) whose every harsher level is detected too; None when the harshest level
        of the grid is not detected (not reached in the grid).
    """
    harsh_first = sorted(
        levels, key=lambda lv: lv["factor"], reverse=effect not in HARSHER_WHEN_SMALLER
    )
    limit = None
    for lv in harsh_first:
        if not lv["detected"]:
            break
        limit = lv
    return limit


def _limit_note(limit: Mapping | None, levels: Sequence[Mapping]) -> str:
    """Why an effect has no limit, or '' when it has one."""
    if limit is not None:
        return ""
    if any(lv["detected"] for lv in levels):
        return "not reached in the grid: the harshest level is missed, milder ones detected"
    return "not reached in the grid"


def score_detection(
    diagnoses: Mapping[str, Mapping],
    keys: Mapping[str, Mapping],
    *,
    rate: float,
    confidence: float,
) -> dict:
    """Unsealed scoring of the detection sweep.

    A session **names** its effect when :func:`imucal.gap.stress.is_named` (explained, or
    noted for ``large_misalignment``, which opens no gap under the exact rotation); a crash
    names nothing. It is a **false positive** when another effect is explained, and on a clean
    session (``effect`` None) when any effect is.

    Parameters
    ----------
    diagnoses : dict
        Session name -> diagnosis (:func:`imucal.gap.checks.diagnose_folder`).
    keys : dict
        Session name -> sealed key (:func:`imucal.gap.blind.render_blind_session` of a
        :func:`detection_plan` spec).
    rate : float
        Detection rate a level needs (0..1): ``named >= ceil(rate n)``.
    confidence : float
        Level of the one-sided Clopper-Pearson lower bound of each rate (0..1).

    Returns
    -------
    dict
        ``criterion`` (``rate``, ``confidence``), ``effects`` (effect -> ``levels``, by factor:
        ``factor``, ``magnitude`` and ``unit`` (:meth:`Effect.magnitude`), ``magnitude_si``
        and ``unit_si``, ``n``, ``named``, ``needed``, ``rate``, ``cp_lower``, ``detected``,
        ``crashed``, ``other_explained``, ``noted_only`` (sessions that note the effect without
        naming it, e.g. ``saturation`` noted by the static fallback), ``median_heldout_shrink`` and
        ``median_magnitude_rel_error`` (|est - true| / true) over the sessions that name the
        effect, None without any; ``limit``: the :func:`detection_limit` level or None, and
        ``limit_note``: why there is none, '' with one),
        ``false_positive`` ([k, n] effect sessions in which another effect is explained),
        ``clean_explained`` and ``clean_noted`` ([k, n] clean sessions in which any effect is
        explained, noted: the false-positive rate on clean sessions), ``clean_sessions``,
        ``false_noted`` ([k, n] sessions in which another effect is noted: the false alarms of
        a ``large_misalignment`` named by ``noted``; ``other_noted`` per level),
        ``crashes``, ``n``, ``sessions`` (the detail).
    """
    if not 0 < rate <= 1 or not 0 < confidence < 1:
        raise ValueError(f"expected 0 < rate <= 1 and 0 < confidence < 1; got {rate}, {confidence}")
    rows, groups, first_key, clean = [], {}, {}, []
    for name in sorted(keys):
        spec, diag = keys[name]["spec"], diagnoses[name]
        effect = spec["effect"]
        crashed = diag.get("failed") is not None
        if effect is None:
            clean.append({
                "name": name, "crashed": crashed, "explained": list(diag.get("explained", [])),
                "noted": list(diag.get("noted", [])),
            })  # fmt: skip
            continue
        named = not crashed and is_named(effect, diag)
        shrink, est = effect_estimate(diag, effect)
        true = keys[name]["magnitude"]["value"]
        row = {
            "name": name, "effect": effect, "factor": spec["factor"], "magnitude_true": true,
            "named": named, "crashed": crashed, "explained": list(diag.get("explained", [])),
            "noted": list(diag.get("noted", [])),
            "other_explained": [e for e in diag.get("explained", []) if e != effect],
            "other_noted": [e for e in diag.get("noted", []) if e != effect],
            "heldout_shrink": shrink, "magnitude_est": est,
            "magnitude_rel_error": abs(est - true) / abs(true) if est is not None and true else None,
        }  # fmt: skip
        rows.append(row)
        groups.setdefault(effect, {}).setdefault(spec["factor"], []).append(row)
        first_key.setdefault((effect, spec["factor"]), keys[name])
    effects = {}
    for effect, by_factor in groups.items():
        levels = [
            _level(by_factor[f], first_key[(effect, f)], rate, confidence)
            for f in sorted(by_factor)
        ]
        limit = detection_limit(effect, levels)
        effects[effect] = {
            "levels": levels,
            "limit": limit,
            "limit_note": _limit_note(limit, levels),
        }
    order = [e for e in CANONICAL if e in effects] + sorted(set(effects) - set(CANONICAL))
    return {
        "criterion": {"rate": rate, "confidence": confidence},
        "n": len(rows),
        "crashes": sum(r["crashed"] for r in rows) + sum(r["crashed"] for r in clean),
        "clean_explained": [sum(bool(r["explained"]) for r in clean), len(clean)],
        "clean_noted": [sum(bool(r["noted"]) for r in clean), len(clean)],
        "clean_sessions": clean,
        "false_positive": [sum(bool(r["other_explained"]) for r in rows), len(rows)],
        "false_noted": [sum(bool(r["other_noted"]) for r in rows), len(rows)],
        "effects": {e: effects[e] for e in order},
        "sessions": rows,
    }
