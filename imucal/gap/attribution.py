"""Attribution: which effects close the gap, selected forward on held-out data.

For each effect of the library the estimator runs on the session and on every replica (its null
gives a detection score). An effect whose estimate is outside the null is added to the twin at
its estimate and rendered with the seeds of the first replicas (common random numbers: the
simulator draws each effect from its own stream, so the difference to those replicas is the
effect alone); the mean difference of the statistics shifts the null. The held-out check uses
parameters estimated on half A of the segments and measures the gap on half B. Effects are
accepted forward while the gap is significant: of the detected effects whose held-out shrink
reaches ``min_heldout_shrink``, the one with the lowest held-out deviance
(:meth:`~imucal.gap.null.NullModel.deviance`: it charges an effect for the spread it adds to
the null, so that a stochastic effect cannot outrank a systematic one by widening it). Once
an effect is accepted, competing explanations are decided on the joint models: a candidate is
evaluated by rendering it *together with* the accepted effects (each at its estimate; at its
half-A estimate for half B) and measuring that joint model's held-out gap, not by adding its
shift alone to theirs (effects on the same readings, such as a drift with temperature and a
g-sensitivity, do not add in every statistic). A backward pass then drops an accepted effect
whose joint model without it holds the held-out gap within ``min_heldout_shrink`` of the one
with it, and reports it as confusable with the others. An effect whose estimate fails
its physics gate (e.g. a rate the Earth cannot have) or that the exact model absorbs
(``opens_gap`` False) is never evaluated.

The gap is significant when a location is in it (Holm over all locations). An effect whose
signature spreads over several locations (the Earth's rate over the north and up components
of the world-fixed rate) can be far beyond its null in its own estimator while no single
location passes Holm; in the full protocol's diagnosis (``own_evidence``) such an effect, and
only it, is evaluated without a location in the gap when its own detection statistic is beyond
its null (:func:`evident_on_its_own`: one-sided, Bonferroni over the library's estimates), and
accepted by the same held-out rule.

Where the twin cannot replay part of what its statistics measure (``unreplayed``: in a
recording with an orientation reference, the reference's error beyond white noise, the
field's uniformity; :data:`imucal.gap.scoring.TWIN_SHORTFALLS`), the gap at those locations is
the twin's shortfall and can neither confirm nor refute a physical effect that does not render
them. An effect with a location of its own outside them that is in the gap (a magnet's
``field_dipole_peak``, a g-sensitivity's ``ref_g_slope``) is then judged on the gap outside
the shortfall's locations plus its own signature (:func:`judged_locations`): a statistic the
effect renders stays its own (the field direction's spread is a shortfall of the twin's
uniform field only until a field fixed in the world closes it), and the effect is charged for
what it leaves there. An effect without such evidence is judged on the whole gap, as
everywhere else.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats as sps

from imucal.gap.effects import EffectModel
from imucal.gap.null import NullModel, holm, total_gap, transform
from imucal.gap.statictwin import StaticTwin
from imucal.gap.twin import Twin


@dataclass
class Candidate:
    """One effect's evaluation (mutable while the selection runs)."""

    name: str
    params: dict | None
    params_a: dict | None
    detect: float
    detect_z: float
    shift: dict = field(default_factory=dict)
    shift_b: dict = field(default_factory=dict)
    gap_before: float | None = None
    gap_after: float | None = None
    heldout_before: float | None = None
    heldout_after: float | None = None
    heldout_deviance: float | None = None
    heldout_deviance_before: float | None = None
    signature: dict = field(default_factory=dict)
    accepted: bool = False
    evaluated: bool = False
    note: str = ""
    blocked: str = ""
    evident: bool = False
    judged: Callable[[tuple], bool] | None = None
    acts_on: Callable[[tuple], bool] | None = None
    flags: tuple = ()

    def criterion(self) -> Callable[[tuple], bool] | None:
        """The locations its gaps are measured on: where it acts (:attr:`acts_on`) and, beside
        what the twin cannot replay, those it is judged on (:attr:`judged`); None for all."""
        keeps = [f for f in (self.judged, self.acts_on) if f is not None]
        if not keeps:
            return None
        return lambda k: all(f(k) for f in keeps)

    @property
    def shrink(self):
        if self.gap_after is None or not self.gap_before:
            return None
        return 1 - self.gap_after / self.gap_before

    @property
    def heldout_shrink(self):
        if self.heldout_after is None or not self.heldout_before:
            return None
        return 1 - self.heldout_after / self.heldout_before


#: Bound of a detection score: a null whose replicas do not vary (no lost packet in any of them)
#: is scored against a relative resolution of 1e-9, so any departure reaches it; it means
#: "departs from a null without spread", not a measured size.
DETECT_Z_CAP = 1e6


def detection_z(value: float, null_values) -> float:
    """Score of an effect estimator's detection statistic against its values on the replicas
    (prediction interval; a null that is constant, e.g. no lost packet in any replica, gets a
    relative resolution), clipped to +-:data:`DETECT_Z_CAP`."""
    vals = np.array([v for v in null_values if v is not None], dtype=float)
    spread = np.std(vals, ddof=1) * np.sqrt(1 + 1 / len(vals)) if len(vals) > 2 else np.inf
    spread = max(spread, 1e-9 * max(abs(np.mean(vals)), abs(value)), 1e-300)
    return float(np.clip((value - np.mean(vals)) / spread, -DETECT_Z_CAP, DETECT_Z_CAP))


def evident_on_its_own(z: float, n_null: int, n_tests: int, alpha: float, detect_z: float) -> bool:
    """Whether an effect's detection statistic is beyond its null on its own, corrected for the
    library: one-sided (an effect raises its statistic), Bonferroni over the ``n_tests``
    estimates scored, with the prediction interval's ``t(n_null - 1)`` (:func:`detection_z`),
    and at least ``detect_z``.

    An effect whose signature spreads over several locations (the Earth's rate over the north
    and up components of the world-fixed rate) can be far beyond its null in its own estimator
    while no single location passes Holm over all of them; its own test is the stronger one.
    """
    from scipy import stats as sps

    if not np.isfinite(z) or n_null < 3 or n_tests < 1 or z < detect_z:
        return False
    return bool(sps.t.sf(z, df=n_null - 1) < alpha / n_tests)


def widened_where_own(shift: Mapping, own: Sequence[Callable[[tuple], bool]]) -> dict:
    """A null shift whose widening (its variance across seeds) is kept only at the locations
    of the effects' own signatures.

    An effect that adds spread widens, through the few seeds it is rendered with, every
    statistic its noise touches; a widened null holds any departure there, so such an effect
    would close gaps it does not explain (a time offset, a warm-up beside a wandering bias).
    Its mean shift is kept everywhere: that is what it predicts.

    Parameters
    ----------
    shift : dict
        Location -> (mean shift, variance), as :func:`statistic_shift`.
    own : sequence of callable
        The effects' signatures, ``key -> bool`` (:meth:`EffectModel.matches`).
    """
    return {k: (m, v if any(o(k) for o in own) else 0.0) for k, (m, v) in shift.items()}


def statistic_shift(pairs) -> dict:
    """Change of the transformed statistics when an effect is added, over seeds.

    Parameters
    ----------
    pairs : iterable of (dict, dict)
        Per seed, the statistics with the effect and without it (same seed, same half).

    Returns
    -------
    dict
        Key -> (mean change, variance of the change across seeds); a seed where a statistic
        is undefined says nothing about it.
    """
    diffs: dict = {}
    for with_effect, clean in pairs:
        for k, v in with_effect.items():
            if k in clean:
                d = transform(k, v) - transform(k, clean[k])
                if np.isfinite(d):
                    diffs.setdefault(k, []).append(d)
    return {
        k: (float(np.mean(v)), float(np.var(v, ddof=1)) if len(v) > 1 else 0.0)
        for k, v in diffs.items()
    }


def _shift(
    twin: Twin | StaticTwin, effects: tuple, replicas, half, n_seeds: int, keep: list | None = None
) -> dict:
    """:func:`statistic_shift` of ``effects`` rendered together on ``half`` over the first
    ``n_seeds`` replicas; ``keep`` receives each rendered replica's session (what the
    estimators read)."""
    pairs = []
    for rep in replicas[:n_seeds]:
        rendered = twin.replica(rep.seed, effects, (half,))
        if keep is not None:
            keep.append(rendered.session)
        pairs.append((rendered.stats[half], rep.stats[half]))
    return statistic_shift(pairs)


def detection_z_given(
    value: float, null_values: Sequence, with_values: Sequence, without_values: Sequence
) -> float:
    """Score of an effect's detection statistic against the null of a twin that holds effects
    already accepted.

    The accepted effects move the statistic by their mean and widen its spread; both are
    measured on replicas rendered with them against the same seeds without them (common random
    numbers: the difference is theirs alone). The score is the session's value less the clean
    null's mean and that mean shift, over the root of the clean null's prediction variance and
    the variance of the shift. A statistic that a wandering bias (say) moves by as much as the
    session shows is then no evidence of another effect.

    Parameters
    ----------
    value : float
        The session's detection statistic.
    null_values : sequence of float
        Its values on the clean replicas of the null.
    with_values, without_values : sequence of float or None
        Its values on replicas rendered with the accepted effects and on the same seeds
        without them (None where the estimator has nothing to estimate from).

    Returns
    -------
    float
        Clipped to +-:data:`DETECT_Z_CAP`, as :func:`detection_z`; NaN with fewer than two pairs or three
        null values.
    """
    vals = np.array([v for v in null_values if v is not None], dtype=float)
    diffs = np.array(
        [a - b for a, b in zip(with_values, without_values, strict=True)
         if a is not None and b is not None],
        dtype=float,
    )  # fmt: skip
    if len(diffs) < 2 or len(vals) < 3:
        return float("nan")
    var = np.var(vals, ddof=1) * (1 + 1 / len(vals)) + np.var(diffs, ddof=1)
    spread = max(np.sqrt(var), 1e-9 * max(abs(np.mean(vals)), abs(value)), 1e-300)
    return float(
        np.clip((value - np.mean(vals) - np.mean(diffs)) / spread, -DETECT_Z_CAP, DETECT_Z_CAP)
    )


def add_shifts(a: Mapping, b: Mapping) -> dict:
    """Sum two statistic shifts (statistic -> (mean shift, variance)), key by key."""
    out = dict(a)
    for k, (m, v) in b.items():
        m0, v0 = out.get(k, (0.0, 0.0))
        out[k] = (m0 + m, v0 + v)
    return out


def attribute(
    twin: Twin | StaticTwin,
    session,
    stats: Mapping,
    replicas: Sequence,
    null_full: NullModel,
    null_b: NullModel,
    models: Mapping[str, EffectModel],
    *,
    alpha: float,
    min_heldout_shrink: float,
    n_seeds: int,
    detect_z: float,
    cannot_show: str = "the session cannot show this effect",
    own_evidence: bool = False,
    unreplayed: Callable[[tuple], bool] | None = None,
) -> tuple[list[Candidate], list[str], dict, dict]:
    """Forward selection of effects (see the module docstring).

    Parameters
    ----------
    twin : Twin or StaticTwin
    session : SessionFit or dict of str to Stream
        What the estimators read (as :attr:`imucal.gap.twin.Replica.session`).
    stats : dict
        Half -> the session's statistics.
    replicas : list of Replica
    null_full, null_b : NullModel
        Null of the whole session and of half B.
    models : dict of str to EffectModel
    alpha, min_heldout_shrink, detect_z : float
        As :func:`select_forward`.
    n_seeds : int
        Replica seeds an effect is rendered with.
    cannot_show : str
        Note of an effect whose estimator finds nothing to estimate from.
    own_evidence : bool
        Whether an effect whose own detection statistic is beyond its null
        (:func:`evident_on_its_own`) is evaluated without a location in the gap (the full
        protocol's diagnosis, where the blind and stress sets check it).
    unreplayed : callable, optional
        ``key -> bool``: the locations whose statistics the twin cannot replay (module
        docstring); None judges every effect on the whole gap.

    Returns
    -------
    candidates : list of Candidate
    rounds : list of dict
        Per selection round, effect -> held-out shrink (evaluated effects).
    explained : list of str
        Accepted effects, in order.
    shift, shift_b : dict
        Total null shift of the accepted effects (full statistics, half B).
    """
    cands = []
    n_null: dict = {}
    null_of: dict = {}
    for name, model in models.items():
        try:
            est = model.estimate(session, None)
            est_a = model.estimate(session, "A")
            null_detect = [model.estimate(r.session, None) for r in replicas] if est else []
            why = cannot_show
        except ValueError as err:  # the estimator needs what these data do not have
            est, why = None, f"the session cannot show this effect: {err}"
        if est is None:
            cands.append(Candidate(name, None, None, float("nan"), float("nan"), note=why))
            continue
        z = detection_z(est.detect, [e.detect for e in null_detect if e is not None])
        null_of[name] = [e.detect if e is not None else None for e in null_detect]
        cand = Candidate(name, est.params, est_a.params if est_a else None, est.detect, z)
        cand.flags = tuple(est.flags)
        n_null[name] = sum(e is not None for e in null_detect)
        if not model.opens_gap:
            cand.blocked = "reported, not attributed: the pipeline's exact model absorbs it"
        elif model.gate is not None and abs(z) >= detect_z:
            cand.blocked = model.gate(est, null_detect, detect_z)
        cand.note = cand.blocked
        cands.append(cand)
    if own_evidence:
        scored = [c for c in cands if np.isfinite(c.detect_z) and models[c.name].opens_gap]
        for c in scored:
            c.evident = evident_on_its_own(c.detect_z, n_null[c.name], len(scored), alpha, detect_z)

    rendered: dict = {}  # accepted names -> the sessions of their replicas (all data)

    def shifts_of_group(group: Sequence[Candidate]) -> tuple[dict, dict]:
        full = tuple(models[c.name].simulator_effect(c.params) for c in group)
        half_a = tuple(models[c.name].simulator_effect(c.params_a or c.params) for c in group)
        keep: list = []
        out = (_shift(twin, full, replicas, None, n_seeds, keep),
               _shift(twin, half_a, replicas, "B", n_seeds))  # fmt: skip
        rendered[frozenset(c.name for c in group)] = keep
        if any(models[c.name].spreads for c in group):
            own = [models[c.name].matches for c in group]
            out = tuple(widened_where_own(sh, own) for sh in out)
        return out

    def z_given(c: Candidate, accepted: Sequence[str]) -> float:
        sessions = rendered.get(frozenset(accepted))
        if not sessions:
            return float("nan")
        model = models[c.name]

        def detect(session):
            try:
                e = model.estimate(session, None)
            except ValueError:
                return None
            return e.detect if e is not None else None

        with_values = [detect(s) for s in sessions]
        return detection_z_given(c.detect, null_of[c.name], with_values,
                                 null_of[c.name][: len(sessions)])  # fmt: skip

    joint: dict = {}

    def joint_shifts(group: Sequence[Candidate]) -> tuple[dict, dict]:
        key = frozenset(c.name for c in group)
        if key not in joint:
            joint[key] = shifts_of_group(group)
        return joint[key]

    explained, shift, shift_b, rounds = select_forward(
        cands, stats, null_full, null_b, lambda c: shifts_of_group((c,)),
        alpha=alpha, min_heldout_shrink=min_heldout_shrink, detect_z=detect_z,
        joint_shifts=joint_shifts, z_given=z_given, unreplayed=unreplayed,
        own={name: model.matches for name, model in models.items()},
    )  # fmt: skip
    return cands, explained, shift, shift_b, rounds


def judged_locations(
    own: Callable[[tuple], bool],
    in_gap: Sequence[tuple],
    unreplayed: Callable[[tuple], bool] | None,
) -> Callable[[tuple], bool] | None:
    """The locations an effect's shrink is measured on (module docstring), or None for all.

    Parameters
    ----------
    own : callable
        ``key -> bool``: the effect's signature (:meth:`EffectModel.matches`).
    in_gap : sequence of tuple
        The locations in the gap now (Holm).
    unreplayed : callable or None
        ``key -> bool``: the locations the twin cannot replay.

    Returns
    -------
    callable or None
        ``key -> bool``, True outside the unreplayed locations and on the effect's own; None
        (the whole gap) without ``unreplayed`` or when none of the effect's own locations
        outside them is in the gap.
    """
    if unreplayed is None or not any(own(k) and not unreplayed(k) for k in in_gap):
        return None
    return lambda k: own(k) or not unreplayed(k)


def select_forward(
    cands: Sequence[Candidate],
    stats: Mapping,
    null_full: NullModel,
    null_b: NullModel,
    shifts_of: Callable[[Candidate], tuple[dict, dict]],
    *,
    alpha: float,
    min_heldout_shrink: float,
    detect_z: float,
    joint_shifts: Callable[[Sequence[Candidate]], tuple[dict, dict]] | None = None,
    z_given: Callable[[Candidate, Sequence[str]], float] | None = None,
    unreplayed: Callable[[tuple], bool] | None = None,
    own: Mapping[str, Callable[[tuple], bool]] | None = None,
) -> tuple[list[str], dict, dict, list[dict]]:
    """The forward selection of the module docstring, on candidates already scored.

    Parameters
    ----------
    cands : list of Candidate
        Updated in place (gaps, notes, ``accepted``).
    stats : dict
        The session's statistics per half (None, 'A', 'B').
    null_full, null_b : NullModel
        Nulls of all statistics and of half B.
    shifts_of : callable
        ``candidate -> (shift, shift_b)``: the null shift of the effect at its estimate (all
        statistics) and at its half-A estimate (half B); called once per evaluated candidate.
    alpha, min_heldout_shrink, detect_z : float
        Without a location in the gap (Holm at ``alpha``) only the candidates whose own
        statistic is beyond its null (``Candidate.evident``) are evaluated.
    joint_shifts : callable, optional
        ``candidates -> (shift, shift_b)``: the null shift of several effects rendered
        together (each at its estimate; at its half-A estimate on half B). A candidate is then
        evaluated as the joint model of the effects already accepted and itself, and the
        backward pass compares joint models; without it the shifts of single effects add.
    z_given : callable, optional
        ``(candidate, accepted names) -> score`` of the candidate's detection statistic
        against the null of the twin with the accepted effects (:func:`detection_z_given`;
        NaN when it cannot be scored). Once effects are accepted, a candidate whose estimate
        they account for (``|score| < detect_z``) is not evaluated: it would only take a
        residual of theirs.
    unreplayed : callable, optional
        ``key -> bool``, the locations the twin cannot replay; with ``own`` (effect name ->
        its signature's ``key -> bool``), an effect with evidence of its own outside them is
        judged on the gap outside them (:func:`judged_locations`, ``Candidate.judged``).
    own : dict of str to callable, optional
        Effect name -> ``key -> bool``, its signature (:meth:`EffectModel.matches`); needed
        with ``unreplayed``.

    Returns
    -------
    explained : list of str
        Accepted effects, in order.
    shift, shift_b : dict
        Total null shift of the accepted effects (full statistics, half B).
    rounds : list of dict
        Per selection round ``{"winner", "shrinks"}`` (the accepted effect or None, and effect
        -> held-out shrink of the evaluated effects), then one ``{"pruned", "by",
        "heldout_shrink"}`` per effect the backward pass dropped.
    """
    by_name = {c.name: c for c in cands}
    combined = _combiner(joint_shifts)
    shift: dict = {}
    shift_b: dict = {}
    explained: list[str] = []
    rounds: list[dict] = []
    while True:
        t_now = null_full.t(stats[None], shift)
        reject_now = holm(null_full.p_values(t_now), alpha)
        significant = bool(reject_now.any())
        in_gap = [k for k, r in zip(null_full.keys, reject_now, strict=True) if r]
        open_ = [c for c in cands if not c.accepted and c.params is not None]
        if not significant:  # only effects whose own statistic is beyond its null
            open_ = [c for c in open_ if c.evident]
        if not open_:
            break
        best = None
        for c in open_:
            c.judged = judged_locations(own[c.name], in_gap, unreplayed) if own else None
            qualifies = _evaluate(
                c, explained, stats, null_full, null_b, (shift, shift_b), shifts_of, combined,
                by_name, alpha=alpha, detect_z=detect_z, z_given=z_given,
                own=own[c.name] if own else None,
                # beside what the twin cannot replay, an effect without evidence of its own
                # outside it is judged on the whole gap (judged_locations)
                where_it_acts=unreplayed is None or c.judged is not None,
            )  # fmt: skip
            shrink = c.heldout_shrink
            qualifies = qualifies and shrink is not None and shrink >= min_heldout_shrink
            if qualifies and (best is None or c.heldout_deviance < best.heldout_deviance):
                best = c
        rounds.append({
            "winner": best.name if best else None,
            "shrinks": {c.name: c.heldout_shrink for c in open_ if c.evaluated},
        })  # fmt: skip
        if best is None:
            break
        best.accepted = True
        explained.append(best.name)
        shift, shift_b = _safe(combined, [by_name[n] for n in explained])
    explained, pruned = prune_backward(
        cands, explained, stats, null_b, min_heldout_shrink, joint_shifts=joint_shifts
    )
    rounds += pruned
    shift, shift_b = _safe(combined, [by_name[n] for n in explained])
    return explained, shift, shift_b, rounds


def signature_scores(
    own: Callable[[tuple], bool],
    null_full: NullModel,
    null_b: NullModel,
    stats: Mapping,
    before: tuple[Mapping, Mapping],
    after: tuple[Mapping, Mapping],
) -> dict:
    """The scores at an effect's own signature locations before and after it joins the twin.

    Parameters
    ----------
    own : callable
        ``key -> bool``, the effect's signature (:meth:`EffectModel.matches`).
    null_full, null_b : NullModel
    stats : dict
        The session's statistics per half.
    before, after : tuple of dict
        The null shifts (all statistics, half B) of the twin without and with the effect.

    Returns
    -------
    dict
        ``keys`` (its signature locations), ``z_before``, ``z_after`` (all data) and
        ``z_after_b`` (half B, the effect at its half-A estimate), one per key (None where a
        location has no score).
    """
    keys = [k for k in null_full.keys if own(k)]
    sig_full, sig_b = null_full.restricted(own), null_b.restricted(own)

    def scores(null: NullModel, half, shift: Mapping) -> list:
        t = dict(zip(null.keys, null.t(stats[half], shift), strict=True))
        return [float(t[k]) if np.isfinite(t.get(k, np.nan)) else None for k in keys]

    return {
        "keys": [list(k) for k in keys],
        "z_before": scores(sig_full, None, before[0]),
        "z_after": scores(sig_full, None, after[0]),
        "z_after_b": scores(sig_b, "B", after[1]),
    }


def _unevaluated(c: Candidate, note: str) -> bool:
    """Mark a candidate not evaluated, with the reason; False (it does not qualify)."""
    c.note = note
    c.gap_after = c.heldout_after = None
    c.evaluated = False
    return False


def _evaluate(
    c: Candidate,
    explained: Sequence[str],
    stats: Mapping,
    null_full: NullModel,
    null_b: NullModel,
    shifts: tuple[dict, dict],
    shifts_of: Callable[[Candidate], tuple[dict, dict]],
    combined: Callable[[Sequence[Candidate]], tuple[dict, dict]],
    by_name: Mapping[str, Candidate],
    *,
    alpha: float,
    detect_z: float,
    z_given: Callable[[Candidate, Sequence[str]], float] | None,
    own: Callable[[tuple], bool] | None,
    where_it_acts: bool = True,
) -> bool:
    """Evaluate one candidate of a round of :func:`select_forward` against the twin with the
    effects already accepted (their null shifts ``shifts``: all statistics, half B): its gaps
    in sample and held out, its held-out deviance and the scores at its own signature.

    A candidate is not evaluated when it is blocked, when its estimate is not beyond the null
    on the side the effect moves it (one-sided: every effect raises its detection statistic;
    a session below the twin is not this effect), when the accepted effects account for it,
    or when its replicas cannot be calibrated. Evaluated, it qualifies only when its own
    signature locations are consistent with the twin's null once it is in the twin (Holm at
    ``alpha`` over them, in sample): an effect that leaves a structured residual where it acts
    is not the cause.

    Returns
    -------
    bool
        Whether the candidate was evaluated and passes its signature's check (the held-out
        shrink is the caller's test).
    """
    shift, shift_b = shifts
    nf, nb = _on(null_full, c.judged), _on(null_b, c.judged)
    c.gap_before, c.heldout_before = nf.gap(stats[None], shift), nb.gap(stats["B"], shift_b)
    c.acts_on = None
    if c.blocked:
        return _unevaluated(c, c.blocked)
    if not c.detect_z >= detect_z:
        return _unevaluated(
            c, f"estimate not beyond the null (z = {c.detect_z:.1f} < {detect_z:g})"
        )
    z_acc = z_given(c, explained) if z_given is not None and explained else float("nan")
    if z_acc < detect_z:
        return _unevaluated(
            c,
            f"estimate within the null of the twin with {', '.join(explained)} "
            f"(z = {z_acc:.1f} < {detect_z:g})",
        )
    if not c.shift:
        try:
            c.shift, c.shift_b = shifts_of(c)
        except ValueError as err:  # its replicas cannot be calibrated: it does not fit
            c.blocked = (
                f"not a fit: a replica rendered with this estimate cannot be calibrated ({err})"
            )
            return _unevaluated(c, c.blocked)
    try:
        with_c, with_c_b = combined([by_name[n] for n in explained] + [c])
    except ValueError:  # the joint replicas cannot be calibrated: the shifts add
        with_c, with_c_b = add_shifts(shift, c.shift), add_shifts(shift_b, c.shift_b)
    if own is not None and where_it_acts:
        c.acts_on = acting_locations(own, null_full, shift, with_c)
        nf, nb = _on(null_full, c.criterion()), _on(null_b, c.criterion())
        c.gap_before = nf.gap(stats[None], shift)
        c.heldout_before = nb.gap(stats["B"], shift_b)
    c.evaluated = True
    c.note = (
        ""
        if c.heldout_before > 0
        else (
            "half B shows no gap beyond noise on the locations it acts on"
            + (" and is judged on" if c.judged is not None else "")
            + ": the held-out check cannot confirm an effect"
        )
    )
    c.gap_after = nf.gap(stats[None], with_c)
    c.heldout_after = nb.gap(stats["B"], with_c_b)
    c.heldout_deviance = null_b.deviance(stats["B"], with_c_b)
    c.heldout_deviance_before = null_b.deviance(stats["B"], shift_b)
    if own is None:
        return True
    c.signature = signature_scores(own, null_full, null_b, stats, shifts, (with_c, with_c_b))
    left = residual_at_signature(c.signature, null_full.df, alpha)
    if left:
        c.note = f"leaves a structured residual where it acts: {left}"
        return False
    return True


#: Share of its own signature's gap an effect must close when a location of it stays in the
#: gap (:func:`residual_at_signature`): a twin that replays an effect a little off leaves some
#: residual where the effect is large; one of the wrong shape closes little of it.
SIGNATURE_SHRINK = 0.9


def residual_at_signature(signature: Mapping, df: int, alpha: float) -> str:
    """The structured residual an effect leaves where it acts, as text; empty when none.

    Its signature locations are tested once the effect is in the twin (Holm at ``alpha`` over
    the signature's scored locations, in sample). A location still in the gap counts against
    the effect unless the effect closes at least :data:`SIGNATURE_SHRINK` of its signature's
    gap (:func:`imucal.gap.null.total_gap` there, before and after): a rendering a little off
    the session's leaves a residual at the few locations where the effect is largest, a wrong
    shape leaves most of it.
    """
    keys = [tuple(k) for k in signature.get("keys", [])]
    z = np.array([np.nan if v is None else v for v in signature.get("z_after", [])], dtype=float)
    if not len(z):
        return ""
    reject = holm(2 * sps.t.sf(np.abs(z), df=df), alpha)
    if not reject.any():
        return ""
    before = np.array([np.nan if v is None else v for v in signature["z_before"]], dtype=float)
    gap_before, gap_after = total_gap(before, df), total_gap(z, df)
    closed = 1 - gap_after / gap_before if gap_before > 0 else 0.0
    if closed >= SIGNATURE_SHRINK:
        return ""
    left = [f"{'/'.join(k[:4])} {k[4]} (z = {v:.1f})" for k, v, r in zip(keys, z, reject) if r]
    more = f" and {len(left) - 3} more" if len(left) > 3 else ""
    return f"{', '.join(left[:3])}{more}; it closes {closed:.0%} of its own locations' gap"


#: A location an effect acts on, besides its signature: the twin with it differs there by more
#: than this many of the null's standard deviations (:func:`acting_locations`).
ACTS_ON_STD = 1.0


def acting_locations(
    own: Callable[[tuple], bool], null: NullModel, before: Mapping, after: Mapping
) -> Callable[[tuple], bool]:
    """The locations an effect acts on: its signature, and where adding it to the twin moves
    the null's mean by more than :data:`ACTS_ON_STD` of its standard deviations.

    An effect's gaps, in sample and held out, are measured there: a location it leaves as it
    was can neither confirm it nor count against it, so an effect beside a large departure it
    does not touch (one outside the library, say) is judged on what it explains, and an effect
    that moves locations outside its signature answers for them.

    Parameters
    ----------
    own : callable
        ``key -> bool``, the effect's signature.
    null : NullModel
        The null of all statistics (its scales).
    before, after : dict
        The null shifts of the twin without and with the effect (all statistics).
    """
    moved = {
        k
        for k, scale in zip(null.keys, null.scale, strict=True)
        if np.isfinite(scale)
        and abs(after.get(k, (0.0, 0.0))[0] - before.get(k, (0.0, 0.0))[0]) > ACTS_ON_STD * scale
    }
    return lambda k: own(k) or k in moved


def _on(null: NullModel, judged: Callable[[tuple], bool] | None) -> NullModel:
    """``null`` on the locations ``judged`` keeps (all of them when it is None)."""
    return null if judged is None else null.restricted(judged)


def _combiner(joint_shifts) -> Callable[[Sequence[Candidate]], tuple[dict, dict]]:
    """``candidates -> (shift, shift_b)`` of their joint model: one candidate's own shifts,
    several rendered together by ``joint_shifts`` (or added when it is None)."""

    def combined(group: Sequence[Candidate]) -> tuple[dict, dict]:
        if len(group) == 1:
            return group[0].shift, group[0].shift_b
        if not group or joint_shifts is None:
            return _added(group)
        return joint_shifts(group)

    return combined


def _added(group: Sequence[Candidate]) -> tuple[dict, dict]:
    shift: dict = {}
    shift_b: dict = {}
    for c in group:
        shift, shift_b = add_shifts(shift, c.shift), add_shifts(shift_b, c.shift_b)
    return shift, shift_b


def _safe(combined, group: Sequence[Candidate]) -> tuple[dict, dict]:
    """The joint model's shifts, or the single effects' added where its replicas cannot be
    calibrated."""
    try:
        return combined(group)
    except ValueError:
        return _added(group)


def prune_backward(
    cands: Sequence[Candidate],
    explained: Sequence[str],
    stats: Mapping,
    null_b: NullModel,
    min_heldout_shrink: float,
    joint_shifts: Callable[[Sequence[Candidate]], tuple[dict, dict]] | None = None,
) -> tuple[list[str], list[dict]]:
    """The backward pass of the selection: an accepted effect must still close its share of
    the held-out gap once the effects accepted after it are in the twin.

    Forward selection can accept an effect early that a later one explains better (two effects
    with overlapping signatures). Each accepted effect's held-out shrink given all the others,
    ``1 - gap(all) / gap(all but it)`` on half B, must reach ``min_heldout_shrink``; the one
    furthest below is dropped (its candidate un-accepted, with a note) and the pass repeats.
    The gaps are those of the joint models (``joint_shifts``, as :func:`select_forward`), or
    of the single effects' shifts added.

    Returns
    -------
    explained : list of str
        The accepted effects left, in acceptance order.
    pruned : list of dict
        Per dropped effect ``{"pruned", "by", "heldout_shrink"}`` (see :func:`confusable`).
    """
    by_name = {c.name: c for c in cands}
    explained = list(explained)
    pruned = []

    combined = _combiner(joint_shifts)

    def gap_b(names, judged) -> float:
        shift_b = _safe(combined, [by_name[n] for n in names])[1]
        return _on(null_b, judged).gap(stats["B"], shift_b)

    while len(explained) > 1:
        marginal = {}
        for name in explained:
            judged = by_name[name].criterion()
            with_all = gap_b(explained, judged)
            without = gap_b([n for n in explained if n != name], judged)
            marginal[name] = 1 - with_all / without if without > 0 else 0.0
        worst = min(explained, key=lambda n: marginal[n])
        if marginal[worst] >= min_heldout_shrink:
            break
        others = [n for n in explained if n != worst]
        c = by_name[worst]
        c.accepted = False
        c.note = (
            f"dropped: once {', '.join(others)} are in the twin it closes "
            f"{marginal[worst]:.2f} of the held-out gap (< {min_heldout_shrink:g}); "
            "confusable with them"
        )
        pruned.append({"pruned": worst, "by": others, "heldout_shrink": marginal[worst]})
        explained = others
    return explained, pruned


def confusable(rounds: Sequence[Mapping], explained: Sequence[str], threshold: float) -> list:
    """Effects the data cannot tell apart from an accepted one.

    Those that qualified in the round an accepted effect won but were not accepted later (once
    the winner was in the twin they no longer closed anything), and those the backward pass
    dropped (:func:`prune_backward`): the data explain the same locations with either.
    ``rounds`` are :func:`select_forward`'s.
    """
    out = []
    for r in rounds:
        if "pruned" in r:
            out.append({"accepted": " + ".join(r["by"]), "rivals": [r["pruned"]],
                        "heldout_shrink": {r["pruned"]: r["heldout_shrink"]}})  # fmt: skip
            continue
        winner, shrinks = r["winner"], r["shrinks"]
        if winner not in explained:
            continue
        rivals = [n for n, s in shrinks.items()
                  if n != winner and n not in explained and (s or 0) >= threshold]  # fmt: skip
        if rivals:
            out.append({"accepted": winner, "rivals": rivals,
                        "heldout_shrink": {n: shrinks[n] for n in [winner, *rivals]}})  # fmt: skip
    return out
