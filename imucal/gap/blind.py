"""The blind check: sessions rendered with hidden effects, diagnosed without their answer keys,
then unsealed and scored.

The plan (which session hides which effect) is drawn from a seed and known only to
:func:`render_blind_session`, which writes the session folder without ``truth.json`` and the
answer key under a separate ``sealed`` path that no diagnosis rule takes as input. Session
names (``b00``, ``b01``, ...) do not reveal the effect. :func:`score_blind` reads the keys
after every diagnosis is done.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from imucal.sim import ProtocolConfig, make_truth, simulate_session, write_session
from imucal.sim.effects import CANONICAL, make_effect, stream_rng
from imucal.sim.outside import make_outside

#: The blind sessions: the default protocol with a 120 s static recording (shorter rate-table
#: plateaus, 4 s, split runs in the automatic segmentation).
BLIND_PROTOCOL = {"static_s": 120.0}

#: Shapes of real parts, drawn per session (:func:`shape_params`): temperature drift per axis
#: with mixed signs at half, once and twice the realistic size (effects.md #1a), and a full
#: g-sensitivity matrix.
SHAPES = {
    "temperature_axes_half": ("temperature_drift", 0.5),
    "temperature_axes": ("temperature_drift", 1.0),
    "temperature_axes_double": ("temperature_drift", 2.0),
    "g_sensitivity_matrix": ("g_sensitivity", 1.0),
}


def _mixed_signs(rng: np.random.Generator, rms: float) -> list[float]:
    """Three per-axis coefficients, each its own size (0.2-1 of the largest) and not all of one
    sign, scaled to the RMS ``rms``."""
    v = rng.uniform(0.2, 1.0, 3)
    v[rng.integers(3)] *= -1
    v *= rng.choice([-1.0, 1.0])
    return (v * rms / np.sqrt(np.mean(v**2))).tolist()


def shape_params(variant: str, rng: np.random.Generator) -> tuple[str, dict]:
    """The effect and the parameters of a real part's shape (:data:`SHAPES`) for one session.

    ``temperature_axes*``: every bias and scale drift of the accelerometer and the gyroscope
    per axis with mixed signs (:func:`_mixed_signs`), each at the RMS of the realistic default
    times the variant's factor. ``g_sensitivity_matrix``: a diagonal of 0.1-0.2 deg/s/g per
    axis (1.8e-4-3.6e-4 rad/s per m/s^2, effects.md #4) of either sign, cross-axis elements
    up to 30 % of 2e-4 of either sign.
    """
    effect, factor = SHAPES[variant]
    if effect == "temperature_drift":
        real = make_effect(effect)
        keys = ("acc_per_k", "gyr_per_k", "acc_scale_per_k", "gyr_scale_per_k")
        rms = {k: factor * float(np.sqrt(np.mean(np.square(getattr(real, k))))) for k in keys}
        return effect, {k: _mixed_signs(rng, rms[k]) for k in keys}
    g = rng.uniform(-0.3, 0.3, (3, 3)) * 2e-4
    np.fill_diagonal(g, rng.uniform(1.8e-4, 3.6e-4, 3) * rng.choice([-1.0, 1.0], 3))
    return effect, {"matrix": (factor * g).tolist()}


def blind_plan(
    seed: int,
    seeds_per_effect: int,
    n_null: int,
    unknown: Mapping[str, int],
    effects=None,
    shapes: int = 0,
) -> list[dict]:
    """The hidden assignment of effects to session names.

    Parameters
    ----------
    seed : int
    seeds_per_effect : int
        Sessions per library effect, each at the effect's realistic magnitude (the simulator's
        defaults).
    n_null : int
        Sessions without any effect.
    unknown : dict
        Effect -> number of unknown-effect sessions (the effect is injected and left out of
        the diagnosis's library).
    effects : list of str, optional
        Effects to hide; default every canonical simulator effect (not the protocol
        conditions such as ``hand_tremor``, which the library does not model).
    shapes : int
        Sessions per real part's shape (:data:`SHAPES`), each drawn with its own shape.

    Returns
    -------
    list of dict
        ``name``, ``effect`` (None for no effect), ``seed``, ``exclude`` (effects left out of the
        library when diagnosing it), in name order; a shape's session also ``effects`` (its
        drawn parameters) and ``shape``.
    """
    effects = sorted(CANONICAL) if effects is None else list(effects)
    specs = [{"effect": e, "exclude": []} for e in effects for _ in range(seeds_per_effect)]
    rng = stream_rng(seed, "blind/shapes")
    for variant in SHAPES:
        for _ in range(shapes):
            effect, params = shape_params(variant, rng)
            specs.append({"effect": effect, "exclude": [], "shape": variant,
                          "effects": [{"effect": effect, "params": params}]})  # fmt: skip
    specs += [{"effect": None, "exclude": []} for _ in range(n_null)]
    specs += [{"effect": e, "exclude": [e]} for e, n in unknown.items() for _ in range(n)]
    order = stream_rng(seed, "blind/plan").permutation(len(specs))
    out = []
    for i, j in enumerate(order):
        out.append({"name": f"b{i:02d}", "seed": int(seed * 1000 + i), **specs[j]})
    return sorted(out, key=lambda s: s["name"])


def public_plan(plan: list[dict]) -> dict:
    """What the diagnosis may know: session name -> effects left out of the library."""
    return {s["name"]: list(s["exclude"]) for s in plan}


def spec_effects(spec: Mapping) -> tuple:
    """The simulator effects of a session spec.

    ``effects`` (a list of ``{"effect": name, "params": {...}}``) when the spec has it, else
    the single ``effect`` (None for none) at its realistic magnitude; an effect of the library
    or one outside it (:mod:`imucal.sim.outside`).
    """
    if "effects" in spec:
        return tuple(make_outside(e["effect"], **e["params"]) for e in spec["effects"])
    return () if spec["effect"] is None else (make_outside(spec["effect"]),)


def render_blind_session(spec: Mapping, folder: str | Path, sealed: str | Path) -> None:
    """Render one blind session to ``folder`` and its answer key to ``sealed`` (JSON).

    Parameters
    ----------
    spec : dict
        ``name``, ``seed`` and the effects (see :func:`spec_effects`); optionally ``preset``
        (truth preset, default 'random'), ``protocol`` (:class:`ProtocolConfig` settings over
        :data:`BLIND_PROTOCOL`; lists become tuples) and ``description``.
    folder : str or Path
        The session's dataset folder, written without ``truth.json``.
    sealed : str or Path
        The answer key: ``spec``, ``magnitude`` (of the first effect, None without one),
        ``magnitudes`` (effect -> magnitude) and ``truth`` (truth.json).
    """
    effects = spec_effects(spec)
    truth = make_truth(spec.get("preset", "random"), stream_rng(spec["seed"], "truth"))
    protocol = {**BLIND_PROTOCOL, **spec.get("protocol", {})}
    config = ProtocolConfig(
        **{k: tuple(v) if isinstance(v, list) else v for k, v in protocol.items()}
    )
    session = simulate_session(
        truth, spec["seed"], config, effects, name=spec["name"],
        description=spec.get("description", "blind session (answer key sealed)"),
    )  # fmt: skip
    folder = Path(folder)
    write_session(session, folder, sealed=True)
    key = json.loads(json.dumps(session.truth_dict(), allow_nan=False))
    magnitudes = {}
    for effect in effects:
        m = effect.magnitude()
        magnitudes[effect.name] = {"value": m.value, "unit": m.unit, "meaning": m.meaning}
    magnitude = magnitudes[effects[0].name] if effects else None
    Path(sealed).parent.mkdir(parents=True, exist_ok=True)
    Path(sealed).write_text(json.dumps(
        {"spec": dict(spec), "magnitude": magnitude, "magnitudes": magnitudes, "truth": key},
        indent=1, default=float,
    ))  # fmt: skip


def failed_diagnosis(dataset: str, error: str) -> dict:
    """The diagnosis record of a session the pipeline refused (scored as a miss)."""
    return {
        "format_version": 1, "dataset": dataset, "failed": error,
        "gap": {"total": None, "null_p95": None, "significant": None},
        "locations": [], "effects": [], "explained": [],
        "remaining": {"total": None, "significant": None, "locations": []},
    }  # fmt: skip


def estimated_magnitude(effect: str, params) -> float | None:
    """Headline magnitude (:meth:`Effect.magnitude`, its unit) of an effect's estimated parameters.

    None when there is no estimate or its parameters make no valid simulator effect.
    """
    if params is None:
        return None
    try:
        return float(make_effect(effect, **params).magnitude().value)
    except (ValueError, TypeError, NotImplementedError):
        return None


def effect_estimate(diagnosis: Mapping, effect: str) -> tuple[float | None, float | None]:
    """What a diagnosis says of one effect: its held-out shrink and estimated magnitude.

    Returns
    -------
    heldout_shrink : float or None
        Fraction of the held-out gap the effect closes; None when it was not evaluated.
    magnitude : float or None
        :func:`estimated_magnitude` of its estimate, in the unit of :meth:`Effect.magnitude`.
    """
    entry = next((e for e in diagnosis["effects"] if e["name"] == effect), None)
    if entry is None:
        return None, None
    return entry["heldout_shrink"], estimated_magnitude(effect, entry["params"])


def score_blind(diagnoses: Mapping[str, Mapping], keys: Mapping[str, Mapping]) -> dict:
    """Unsealed scoring of the blind check.

    Returns
    -------
    dict
        ``confusion`` (true effect -> first explained effect, else first noted effect marked
        '(noted)', or 'none' -> count), ``top1`` (fraction of effect sessions whose first
        explained effect is the hidden one, or, with nothing explained, whose first noted
        one is), ``top1_explained_only`` (the first explained effect only),
        ``n`` and ``crashes`` (sessions, and those whose diagnosis failed), ``fully_right``
        ([k, n]: a session with an effect explains it alone, or notes it with nothing explained
        where it opens no gap; one without explains nothing; one with an effect the library
        was denied flags a remaining gap and names nothing else), ``null_explained_empty`` (k
        of n no-effect sessions), ``magnitude_rel_error`` (per
        effect, median |est - true| / true), ``heldout_shrink_true`` (median over effect
        sessions of the true effect's held-out shrink, 0 when not evaluated), ``unknown``
        (per unknown-effect session: flagged, locations, named), ``sessions`` (the detail).
    """
    confusion: dict = {}
    sessions, hits, hits_explained, n_eff, shrinks, rel = [], 0, 0, 0, [], {}
    null_ok = n_null = 0
    unknown = []
    for name in sorted(keys):
        key, diag = keys[name], diagnoses[name]
        spec = key["spec"]
        truth_effect = spec["effect"] or "none"
        # an effect that opens no gap (large misalignment under the exact rotation) is
        # identified when it is reported in ``noted`` and nothing is explained
        noted = diag.get("noted", [])
        named = diag["explained"][0] if diag["explained"] else None
        first = named or (f"{noted[0]} (noted)" if noted else "none")
        hit = named == truth_effect or (named is None and bool(noted) and noted[0] == truth_effect)
        row = {"name": name, "effect": truth_effect, "explained": diag["explained"],
               "gap_significant": diag["gap"]["significant"],
               "remaining_significant": diag["remaining"]["significant"],
               "noted": noted, "failed": diag.get("failed")}  # fmt: skip
        explained = set(diag["explained"])
        row["fully_right"] = diag.get("failed") is None and (
            explained == {truth_effect} or (not explained and truth_effect in (*noted, "none"))
        )
        if spec["exclude"]:
            named_wrong = [e for e in diag["explained"] if e != truth_effect]
            flagged = bool(diag["remaining"]["significant"]) and not named_wrong
            row["fully_right"] = diag.get("failed") is None and flagged
            row.update(
                unknown=True,
                flagged=flagged,
                remaining_locations=[
                    "/".join((d["stage"], d["sensor"], d["axis"], d["statistic"]))
                    for d in diag["remaining"]["locations"][:6]
                ],
            )
            unknown.append(row)
            sessions.append(row)
            continue
        confusion.setdefault(truth_effect, {}).setdefault(first, 0)
        confusion[truth_effect][first] += 1
        if spec["effect"] is None:
            n_null += 1
            null_ok += not diag["explained"]
        else:
            n_eff += 1
            hits += hit
            hits_explained += named == truth_effect
            hs, est = effect_estimate(diag, truth_effect)
            hs = 0.0 if hs is None else hs
            shrinks.append(hs)
            true = key["magnitude"]["value"] if key["magnitude"] else None
            if est is not None and true:
                rel.setdefault(truth_effect, []).append(abs(est - true) / abs(true))
            row.update(heldout_shrink=hs, magnitude_true=true, magnitude_est=est)
        sessions.append(row)
    return {
        "n": len(sessions),
        "crashes": sum(r["failed"] is not None for r in sessions),
        "fully_right": [sum(r["fully_right"] for r in sessions), len(sessions)],
        "top1": hits / n_eff if n_eff else None,
        "top1_explained_only": hits_explained / n_eff if n_eff else None,
        "n_effect_sessions": n_eff,
        "null_explained_empty": [null_ok, n_null],
        "median_heldout_shrink_true": float(np.median(shrinks)) if shrinks else None,
        "magnitude_rel_error": {k: float(np.median(v)) for k, v in sorted(rel.items())},
        "confusion": confusion,
        "unknown": unknown,
        "sessions": sessions,
    }
