"""The one assembly of diagnosis.json from a twin's null: scores, attribution, verdict.

Every scope of the diagnosis (the full protocol, :mod:`imucal.gap.diagnosis`; a static
recording, :mod:`imucal.gap.static`; a partial session's parts, :mod:`imucal.gap.composite`;
static poses, :mod:`imucal.gap.poses`) renders its twin's replicas and hands them here:
:func:`scored_diagnosis` scores every location against the null, attributes the gap to effects
held out and writes ``diagnosis.json`` (``format_version``, ``dataset``, ``gap``,
``locations``, ``effects``, ``explained``, ``remaining``) with its ``verdict``
(:func:`verdict_of`), the outcome a user can act on in one sentence.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields

import numpy as np

from imucal.gap.attribution import DETECT_Z_CAP, Candidate, attribute, confusable
from imucal.gap.effects import EffectModel
from imucal.gap.null import build_null, holm, run_replicas
from imucal.gap.statictwin import StaticTwin
from imucal.gap.twin import Replica, Twin

FORMAT_VERSION = 1
LOCATION_FIELDS = ("stage", "sensor", "axis", "segment", "statistic")
#: What the twin does not replay, by the statistics that show it: (stage, statistics, what).
#: The twin renders regular sample times without loss, the session's noise as white noise,
#: bias instability and bias random walk (partial sessions) and its reference with white
#: orientation noise through the measured clock and mounting, in a uniform field; a gap left in
#: these statistics is a shortfall of that model, not a physical effect (``ref_scale`` is
#: among them: a gyroscope calibrated against the reference matches its scale, so a held-out
#: recording departs there through the reference as much as through the sensor). Statistics
#: not listed respond to physical effects (temperature, g-sensitivity, misalignment...).
TWIN_SHORTFALLS = (
    ("ingest", ("loss_fraction", "stamp_scatter_s", "stamp_wander_s", "burst_fraction",
                "long_gap_fraction"), "the host's receive timing"),
    ("noise", ("adev_10s_excess", "adev_long_excess", "trend_per_s", "rest_adev_excess",
               "rest_trend_per_s"), "the sensor's slow bias drift"),
    ("noise", ("rest_noise", "rest_still_fraction"), "the sensor's white noise and quantisation"),
    ("reference", ("resid_rms", "rate2", "rate3", "ref_scale", "ori_median_rad"),
     "the reference's error beyond white noise (smoothing, latency, glitches)"),
    ("reference", ("dir_resid_rad",), "a uniform magnetic field"),
    ("field_fit", ("fit_resid_rms", "fit_resid_slow", "fit_resid_direction"),
     "the field's constancy and the magnetometer's response beyond white noise about its fit"),
)  # fmt: skip
#: Library effects that model the reference rather than the sensor or the world: accepted,
#: they name what the twin's reference lacks.
REFERENCE_EFFECTS = {"reference_jitter": "the reference's sample timing (reference_jitter)"}
#: Library effects of the acquisition (the host, the logger, the clocks) rather than of the
#: sensor or the world; the verdict names their kind, so that a user does not read a receive
#: latency as a physical disturbance. Every other effect is ``physical``.
ACQUISITION_EFFECTS = ("packet_loss", "timing_jitter", "time_offset", "clock_drift")


@dataclass(frozen=True)
class DiagnosisSettings:
    """Settings of a diagnosis: the config section ``gap`` (defaults are the schema's).

    Attributes
    ----------
    replicas : int
        Twin replicas in the null (>= 5).
    alpha : float
        Family-wise level of the location test (Holm), in (0, 1).
    seed : int
        First replica seed.
    min_heldout_shrink : float
        Smallest held-out shrink (0..1) for an effect to be accepted.
    crn_seeds : int
        Replica seeds an effect is rendered with to measure its shift of the statistics.
    detect_z : float
        Smallest |score| of an effect's estimate against the null for it to be evaluated.
    exclude : tuple of str
        Effects left out of the library (the unknown-effect check).
    """

    replicas: int = 20
    alpha: float = 0.05
    seed: int = 1000
    min_heldout_shrink: float = 0.3
    crn_seeds: int = 3
    detect_z: float = 4.0
    exclude: tuple = ()

    def __post_init__(self) -> None:
        if self.replicas < 5:
            raise ValueError(
                f"the null needs at least 5 replicas for a spread, got {self.replicas}"
            )
        if not 0 < self.alpha < 1:
            raise ValueError(f"alpha is a probability in (0, 1), got {self.alpha}")
        object.__setattr__(self, "exclude", tuple(self.exclude))

    @classmethod
    def from_config(cls, section: Mapping) -> DiagnosisSettings:
        """Settings from a config section ``gap`` (a mapping with any of the fields)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(section) - known)
        if unknown:
            raise ValueError(f"unknown diagnosis settings {unknown}; known: {sorted(known)}")
        return cls(**section)

    def describe(self) -> dict:
        """The settings a diagnosis.json records (the replica count is under ``null``)."""
        return {
            "seed": self.seed,
            "min_heldout_shrink": self.min_heldout_shrink,
            "crn_seeds": self.crn_seeds,
            "detect_z": self.detect_z,
            "exclude": list(self.exclude),
        }


def _locations(keys, t, reject, only_significant: bool) -> list[dict]:
    out = [
        {**dict(zip(LOCATION_FIELDS, k, strict=True)), "z": float(z), "in_gap": bool(r)}
        for k, z, r in zip(keys, t, reject, strict=True)
        if np.isfinite(z) and (r or not only_significant)
    ]
    return sorted(out, key=lambda d: -abs(d["z"]))


def _finite_or_none(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def _effect_record(c: Candidate, model: EffectModel, keys, reject) -> dict:
    return {
        "name": c.name,
        "params": c.params,
        "gap_before": c.gap_before,
        "gap_after": c.gap_after,
        "shrink": c.shrink,
        "heldout_shrink": c.heldout_shrink,
        "heldout_deviance": c.heldout_deviance,
        "heldout_deviance_before": c.heldout_deviance_before,
        "signature": c.signature or None,
        # judged beside the twin's shortfalls (attribution.judged_locations); None: not evaluated
        "judged_beside_shortfalls": (c.judged is not None) if c.evaluated else None,
        "accepted": c.accepted,
        "detect": _finite_or_none(c.detect),
        # a detection statistic whose replicas do not vary departs or not by exact match:
        # no score is reported for it (detection_z gives it its resolution's 1e6)
        "detect_z": _finite_or_none(c.detect_z) if abs(c.detect_z) < DETECT_Z_CAP else None,
        "detect_null_without_spread": bool(abs(c.detect_z) >= DETECT_Z_CAP),
        "evident": c.evident,
        "evaluated": c.evaluated,
        "signature_hits": [
            dict(zip(LOCATION_FIELDS, k, strict=True))
            for k, r in zip(keys, reject, strict=True)
            if r and model.matches(k)
        ],
        "note": c.note,
        # what the estimator refused to report as an estimate, with the reason
        "flags": list(c.flags),
    }


def _effect_order(c: Candidate) -> tuple:
    """Accepted first, then by held-out shrink (an effect without one last)."""
    shrink = c.heldout_shrink if c.heldout_shrink is not None else -np.inf
    return (not c.accepted, -shrink)


def unreplayed(key: tuple) -> bool:
    """Whether a location is a statistic of the reference comparison that the twin does not
    replay (:data:`TWIN_SHORTFALLS` of stage ``reference``: the reference's error beyond white
    noise, the field's uniformity)."""
    location = dict(zip(LOCATION_FIELDS, key, strict=True))
    return location["stage"] == "reference" and _shortfall(location) is not None


def _shortfall(location: Mapping) -> str | None:
    """What the twin lacks when a location departs, or None for a physical statistic."""
    for stage, statistics, what in TWIN_SHORTFALLS:
        if location["stage"] == stage and location["statistic"] in statistics:
            return what
    return None


def _name(location: Mapping) -> str:
    parts = [location[f] for f in LOCATION_FIELDS[:4] if location[f] not in ("-", "all")]
    if location.get("z") is None:  # a statistic the twin reproduces exactly (no spread)
        return (f"{'/'.join(parts)} {location['statistic']} ({location['value']:.3g} where "
                f"the twin always has {location['twin']:.3g})")  # fmt: skip
    return f"{'/'.join(parts)} {location['statistic']} (z = {location['z']:.3g})"


def verdict_of(result: Mapping) -> dict:
    """The diagnosis in one of three outcomes a user can act on, and one sentence.

    * ``nothing beyond the model``: no location is in the gap;
    * ``effect``: an effect of the sensor, the platform or the acquisition was accepted (it
      shrinks the gap held out by at least the settings' ``min_heldout_shrink``); the
      sentence names it with its kind (``physical`` or ``acquisition``,
      :data:`ACQUISITION_EFFECTS`) and its held-out shrink;
    * ``twin lacks``: the gap is significant and no such effect closes it. What the twin
      lacks is read from where the remaining gap lies: statistics of what the twin does not
      replay (:data:`TWIN_SHORTFALLS`: receive timing, slow noise, the reference's error, the
      field's uniformity), an accepted reference effect (:data:`REFERENCE_EFFECTS`), or, for
      a gap in a statistic of a physical response that no library effect closes, "an effect
      the library does not hold" at those locations.

    Parameters
    ----------
    result : dict
        diagnosis.json as :func:`scored_diagnosis` assembles it (``gap``, ``effects``,
        ``remaining``; ``explained`` orders the accepted effects).

    Returns
    -------
    dict
        ``outcome``, ``sentence``, ``effects`` (accepted, with ``kind`` and ``heldout_shrink``),
        ``lacks`` (what, share of the remaining gap's squared scores, locations, top
        location), in that order of share.
    """
    gap = result["gap"]
    order = {name: k for k, name in enumerate(result.get("explained", []))}
    accepted = sorted(
        (e for e in result["effects"] if e["accepted"]), key=lambda e: order.get(e["name"], 0)
    )
    physical = [e for e in accepted if e["name"] not in REFERENCE_EFFECTS]
    named = [
        {
            "name": e["name"],
            "kind": "acquisition" if e["name"] in ACQUISITION_EFFECTS else "physical",
            "heldout_shrink": e["heldout_shrink"],
            "judged_beside_shortfalls": bool(e.get("judged_beside_shortfalls")),
            "params": e["params"],
        }
        for e in physical
    ]
    groups: dict = {}
    for e in accepted:
        if e["name"] in REFERENCE_EFFECTS:
            what = REFERENCE_EFFECTS[e["name"]]
            groups[what] = {"what": what, "weight": 0.0, "locations": [], "effect": e["name"]}
    remaining = result["remaining"]["locations"] if result["remaining"]["significant"] else []
    for loc in remaining:
        what = _shortfall(loc) or "an effect the library does not hold"
        g = groups.setdefault(what, {"what": what, "weight": 0.0, "locations": []})
        g["weight"] += loc["z"] ** 2
        g["locations"].append(loc)
    for loc in result.get("null", {}).get("constant_departures", []):
        what = _shortfall(loc) or "an effect the library does not hold"
        g = groups.setdefault(what, {"what": what, "weight": 0.0, "locations": []})
        g["locations"].append({**loc, "z": None})
    total = sum(g["weight"] for g in groups.values()) or 1.0
    lacks = [
        {
            "what": g["what"],
            "share": g["weight"] / total,
            "locations": len(g["locations"]),
            "top": _name(g["locations"][0]) if g["locations"] else None,
            **({"effect": g["effect"]} if "effect" in g else {}),
        }
        for g in sorted(groups.values(), key=lambda g: -g["weight"])
    ]
    if not gap["significant"]:
        outcome = "nothing beyond the model"
        sentence = (
            "Nothing beyond the model: no location departs from the session's twin (total gap "
            f"{gap['total']:.3g} against a null 95th percentile of {gap['null_p95']:.3g})."
        )
    elif named:
        outcome = "effect"
        sentence = "Effect " + "; then ".join(
            f"{e['name']} ({e['kind']}), shrink {e['heldout_shrink']:.1%} held out"
            + (", judged beside what the twin lacks" if e["judged_beside_shortfalls"] else "")
            for e in named
        )
        sentence += (
            f"; the twin still lacks {lacks[0]['what']} (at {lacks[0]['top']})."
            if lacks and lacks[0]["top"]
            else "."
        )
    else:
        outcome = "twin lacks"
        top = lacks[0] if lacks else {"what": "an effect the library does not hold", "top": None}
        also = f"; also {lacks[1]['what']}" if len(lacks) > 1 else ""
        if "effect" in top:
            shrink = next(e["heldout_shrink"] for e in accepted if e["name"] == top["effect"])
            sentence = (
                f"The twin lacks {top['what']}: {top['effect']} shrinks the gap {shrink:.1%} "
                f"held out{also}."
            )
        else:
            at = f", above all at {top['top']}" if top.get("top") else ""
            sentence = (
                f"The twin lacks {top['what']}{at}{also}: no effect of the library closes "
                "the gap held out."
            )
    return {"outcome": outcome, "sentence": sentence, "effects": named, "lacks": lacks}


def scored_diagnosis(
    twin: Twin | StaticTwin,
    session,
    stats: Mapping,
    replicas: Sequence[Replica],
    models: Mapping[str, EffectModel],
    *,
    dataset: str,
    settings: DiagnosisSettings,
    cannot_show: str = "the session cannot show this effect",
    own_evidence: bool = False,
    beside_shortfalls: bool = False,
) -> dict:
    """Score a session against its twin's replicas and attribute its gap: the part of
    diagnosis.json that the full and the static diagnosis share.

    Parameters
    ----------
    twin : Twin or StaticTwin
    session : SessionFit or dict of str to Stream
        What the effect estimators read (:attr:`imucal.gap.twin.Replica.session`).
    stats : dict
        Half (None, 'A', 'B') -> the session's statistics.
    replicas : list of Replica
        The null's replicas (>= 5).
    models : dict of str to EffectModel
        The effect library.
    dataset : str
    settings : DiagnosisSettings
        Its ``alpha``, ``min_heldout_shrink``, ``crn_seeds`` and ``detect_z``.
    cannot_show : str
        Note of an effect whose estimator finds nothing to estimate from.
    own_evidence : bool
        As :func:`imucal.gap.attribution.attribute`.
    beside_shortfalls : bool
        Whether an effect with evidence of its own outside the statistics the twin does not
        replay is judged on the gap outside them (:func:`unreplayed`; the reference scope,
        whose twin's reference has white noise only).

    Returns
    -------
    dict
        ``format_version``, ``dataset``, ``gap``, ``locations``, ``effects``, ``explained``,
        ``remaining``, ``confusable``, ``all_locations``, ``null`` (with the locations whose
        replicas are all equal, which have no score: ``constant_locations``), ``verdict``
        (:func:`verdict_of`).
    """
    alpha = settings.alpha
    null_full = build_null(replicas, None, stats[None])
    null_b = build_null(replicas, "B", stats["B"])
    keys = null_full.keys
    t_real = null_full.t(stats[None])
    reject = holm(null_full.p_values(t_real), alpha)
    loo = null_full.leave_one_out_gaps()
    cands, explained, shift, _, rounds = attribute(
        twin, session, stats, replicas, null_full, null_b, models,
        alpha=alpha, min_heldout_shrink=settings.min_heldout_shrink, n_seeds=settings.crn_seeds,
        detect_z=settings.detect_z, cannot_show=cannot_show, own_evidence=own_evidence,
        unreplayed=unreplayed if beside_shortfalls else None,
    )  # fmt: skip
    t_after = null_full.t(stats[None], shift)
    reject_after = holm(null_full.p_values(t_after), alpha)
    departs = [
        {**dict(zip(LOCATION_FIELDS, k, strict=True)), "value": x, "twin": m}
        for k, x, m in null_full.constant_departures(stats[None])
    ]
    result = {
        "format_version": FORMAT_VERSION,
        "dataset": dataset,
        "gap": {
            "total": null_full.gap(stats[None]),
            "null_p95": float(np.percentile(loo, 95)),
            # a location in the gap, an accepted effect beyond its null on its own, or a
            # statistic the twin reproduces exactly that the session does not have
            "significant": bool(reject.any())
            or any(c.accepted and c.evident for c in cands)
            or bool(departs),
        },
        "locations": _locations(keys, t_real, reject, True),
        "effects": [
            _effect_record(c, models[c.name], keys, reject)
            for c in sorted(cands, key=_effect_order)
        ],
        "explained": explained,
        "remaining": {
            "total": null_full.gap(stats[None], shift),
            "significant": bool(reject_after.any()),
            "locations": _locations(keys, t_after, reject_after, True),
        },
        "confusable": confusable(rounds, explained, settings.min_heldout_shrink),
        "all_locations": _locations(keys, t_real, reject, False),
        "null": {
            "replicas": len(replicas),
            "alpha": alpha,
            "n_locations": len(keys),
            "loo_gap_median": float(np.median(loo)),
            "loo_false_alarm": float(np.mean(null_full.leave_one_out_flags(alpha))),
            "constant_locations": [
                dict(zip(LOCATION_FIELDS, k, strict=True)) for k in null_full.constant
            ],
            # compared by exact match (no spread to score against): where the session differs
            "constant_departures": departs,
        },
    }
    return {**result, "verdict": verdict_of(result)}


def scope_diagnosis(
    twin: Twin | StaticTwin,
    session,
    stats: Mapping,
    library: Mapping[str, EffectModel],
    *,
    scope: str,
    not_observable: Mapping[str, str],
    cannot_show: str,
    dataset: str,
    settings: DiagnosisSettings,
    started: float,
    beside_shortfalls: bool = False,
    **described,
) -> dict:
    """diagnosis.json of one scope: the twin's replicas run, the session scored against them
    (:func:`scored_diagnosis`, the library less ``settings.exclude``) and the scope's record.

    Parameters
    ----------
    twin, session, stats
        As in :func:`scored_diagnosis`.
    library : dict of str to EffectModel
        The scope's effects.
    scope : str
        The scope's name in the record.
    not_observable : dict of str to str
        Effect -> why the scope cannot show it.
    cannot_show : str
        As in :func:`scored_diagnosis`.
    dataset : str
    settings : DiagnosisSettings
    started : float
        ``time.perf_counter()`` when the diagnosis began (``timing_s`` counts from it).
    beside_shortfalls : bool
        As in :func:`scored_diagnosis`.
    **described
        Further entries of the record, placed after ``scope`` (e.g. ``static_source``).

    Returns
    -------
    dict
        :func:`scored_diagnosis`'s result with ``scope``, the ``described`` entries,
        ``not_observable``, ``twin``, ``settings`` and ``timing_s`` (``null``, ``total``; s).
    """
    replicas = run_replicas(twin, settings.replicas, settings.seed)
    t_null = time.perf_counter()
    models = {k: m for k, m in library.items() if k not in settings.exclude}
    result = scored_diagnosis(
        twin, session, stats, replicas, models, dataset=dataset, settings=settings,
        cannot_show=cannot_show, beside_shortfalls=beside_shortfalls,
    )  # fmt: skip
    return {
        **result,
        "scope": scope,
        **described,
        "not_observable": dict(not_observable),
        "twin": twin.describe(),
        "settings": settings.describe(),
        "timing_s": {"null": t_null - started, "total": time.perf_counter() - started},
    }
