"""The sim-vs-sim null: replicas of the twin with fresh noise, refit by the same pipeline, and
the scores of a session's statistics against them.

Scores are prediction-interval t statistics: with ``R`` replicas of mean ``m`` and standard
deviation ``s`` (plus the statistic's resolution ``f`` in quadrature), a new draw from the null
satisfies ``(x - m) / (sqrt(s^2 + f^2) sqrt(1 + 1/R)) ~ t(R - 1)`` when the statistic is close
to Gaussian, which is what the log transforms of :data:`~imucal.gap.statistics.CATALOGUE` are
for. Locations are declared in the gap by Holm's step-down procedure at family-wise level
``alpha`` over all locations. The total gap is the sum of squared scores beyond what noise alone
gives: ``max(sum t^2 - sum_l w_l df / (df - 2), 0)`` over the scored locations (``df / (df - 2)``
is the mean of ``t^2`` for ``t ~ t(df)``, and ``w_l = s^2 / (s^2 + f^2)`` the share of a
location's scale that is the replicas' spread rather than its resolution floor: a location
whose floor dominates scores near 0 under the null, and charging it the full mean would leave
the gap of every replica at 0 and the null's 95th percentile with it), so that the share of it an effect closes does not
shrink as statistics are added. Its null 95th percentile comes from scoring each replica against
the other ``R - 1`` (leave-one-out), which includes the small-sample inflation of the scores.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from imucal.gap.statictwin import StaticTwin
from imucal.gap.statistics import CATALOGUE, Key
from imucal.gap.twin import Replica, Twin

#: Relative size of the round-off of a statistic: replicas that differ by less than this share
#: of their size do not vary (:meth:`NullModel.from_values`).
ROUND_OFF = 1e-9


def transform(key: Key, value: float) -> float:
    """The scored form of a statistic (log for scale statistics)."""
    info = CATALOGUE[key[4]]
    if info.log:
        return float(np.log(max(value, 1e-300)))
    return float(value)


def run_replicas(twin: Twin | StaticTwin, n: int, seed: int) -> list[Replica]:
    """``n`` replicas of either twin with seeds ``seed, seed + 1, ...``."""
    if n < 5:
        raise ValueError(f"the null needs at least 5 replicas for a spread, got {n}")
    return [twin.replica(seed + i) for i in range(n)]


@dataclass(frozen=True)
class NullModel:
    """Mean and spread of each (transformed) statistic over the replicas.

    Attributes
    ----------
    keys : list of Key
    mean, scale : ndarray, shape (L,)
        Replica mean and ``sqrt(s^2 + floor^2) sqrt(1 + 1/R)``.
    values : ndarray, shape (R, L)
        Transformed replica values.
    spread_share : ndarray, shape (L,), optional
        ``s^2 / (s^2 + floor^2)`` per location: the share of the null mean of ``t^2`` that
        noise gives there (:func:`total_gap`); all 1 when omitted.
    """

    keys: list
    mean: np.ndarray
    scale: np.ndarray
    values: np.ndarray
    spread_share: np.ndarray | None = None

    @property
    def n_replicas(self) -> int:
        return self.values.shape[0]

    @classmethod
    def from_values(cls, keys: Sequence[Key], values: np.ndarray) -> NullModel:
        """The null of replica values, shape (R, L) (transformed units).

        A location whose replicas do not vary (all equal, or differing by round-off only:
        a spread below :data:`ROUND_OFF` of the values' size) and whose statistic has no
        resolution floor (:data:`~imucal.gap.statistics.CATALOGUE`) gives no spread to score
        against: its scale is NaN, so it has no score (rather than one of 1e15 for any
        departure, which would put every session in the gap there and leave the null's own
        leave-one-out gaps at 0). :attr:`constant` names those locations; a session is
        compared with them by exact match (:meth:`constant_departures`).
        """
        r = values.shape[0]
        mean = np.nanmean(values, axis=0)
        std = np.nanstd(values, axis=0, ddof=1)
        size = np.nanmax(np.abs(values), axis=0, initial=0.0)
        std = np.where(std > ROUND_OFF * size, std, 0.0)
        floor = np.array([CATALOGUE[k[4]].floor for k in keys])
        scale = np.sqrt(std**2 + floor**2) * np.sqrt(1 + 1 / r)
        ok = scale > 0
        share = np.divide(std**2, std**2 + floor**2, out=np.zeros_like(scale), where=ok)
        return cls(list(keys), mean, np.where(ok, scale, np.nan), values, share)

    def restricted(self, keep: Callable[[Key], bool]) -> NullModel:
        """This null on some of its locations (the same replicas).

        Parameters
        ----------
        keep : callable
            ``key -> bool``, True for the locations to keep.

        Returns
        -------
        NullModel
            The kept locations' mean, scale, values and spread share, in this null's order.
        """
        idx = [i for i, k in enumerate(self.keys) if keep(k)]
        share = None if self.spread_share is None else self.spread_share[idx]
        return NullModel(
            [self.keys[i] for i in idx],
            self.mean[idx],
            self.scale[idx],
            self.values[:, idx],
            share,
        )

    @property
    def constant(self) -> list:
        """Locations the null cannot score: replicas that do not vary, no resolution floor."""
        return [k for k, s in zip(self.keys, self.scale, strict=True) if not np.isfinite(s)]

    def _values(self, stats: Mapping[Key, float]) -> np.ndarray:
        """A session's statistics in this null's order, transformed (NaN where it lacks one)."""
        return np.array([transform(k, stats[k]) if k in stats else np.nan for k in self.keys])

    def _without_spread(self, x: np.ndarray) -> np.ndarray:
        """Per location, whether the null has no spread to score ``x`` against: no scale, or
        one below :data:`ROUND_OFF` of the size of ``x`` and the mean (round-off of a value
        the replicas share)."""
        size = np.maximum(np.abs(x), np.abs(self.mean))
        with np.errstate(invalid="ignore"):
            return ~np.isfinite(self.scale) | (self.scale <= ROUND_OFF * size)

    def constant_departures(self, stats: Mapping[Key, float]) -> list[tuple[Key, float, float]]:
        """The locations where the null has no spread to score the session against (its
        replicas do not vary, :attr:`constant`, or vary by round-off of the values' size) and
        the session's statistic is not the replicas' value: ``(key, session value, replicas'
        value)``, transformed units.

        They are compared by exact match, within :data:`ROUND_OFF` of the larger size: the twin
        reproduces the value exactly, so any other value departs, by an amount that has no
        score.
        """
        x = self._values(stats)
        none = self._without_spread(x)
        out = []
        for i, k in enumerate(self.keys):
            m = float(self.mean[i])
            if none[i] and np.isfinite(x[i]) and abs(x[i] - m) > ROUND_OFF * max(abs(x[i]), abs(m)):
                out.append((k, float(x[i]), m))
        return out

    def t(self, stats: Mapping[Key, float], shift: Mapping | None = None) -> np.ndarray:
        """Scores of a session's statistics, shape (L,) (NaN where the session lacks one, or
        where the null has no spread to score it against: :meth:`constant_departures`).

        ``shift`` (key -> (mean, variance), transformed units) moves the null mean by an
        effect added to the twin and widens it by the effect's own scatter across seeds.
        """
        x = self._values(stats)
        shift = shift or {}
        d = np.array([shift.get(k, (0.0, 0.0))[0] for k in self.keys])
        v = np.array([shift.get(k, (0.0, 0.0))[1] for k in self.keys])
        t = (x - self.mean - d) / np.sqrt(self.scale**2 + v)
        return np.where(self._without_spread(x), np.nan, t)

    @property
    def df(self) -> int:
        """Degrees of freedom of the scores."""
        return self.n_replicas - 1

    def p_values(self, t: np.ndarray) -> np.ndarray:
        return 2 * sps.t.sf(np.abs(t), df=self.df)

    def gap(self, stats: Mapping[Key, float], shift: Mapping | None = None) -> float:
        """The total gap (:func:`total_gap`) of a session's statistics against this null,
        moved by ``shift``."""
        return total_gap(self.t(stats, shift), self.df, self.spread_share)

    def deviance(self, stats: Mapping[Key, float], shift: Mapping | None = None) -> float:
        """Gaussian deviance of a session's statistics against this null moved by ``shift``:
        the sum over locations of ``t^2 + log(1 + v / scale^2)``, ``v`` the shift's own
        scatter across seeds. Unlike the gap it charges an effect for the spread it adds, so
        an effect cannot win by making the null wide enough to hold anything; it ranks the
        effects (lower is better)."""
        t = self.t(stats, shift)
        v = np.array([(shift or {}).get(k, (0.0, 0.0))[1] for k in self.keys])
        ok = np.isfinite(t)
        return float(np.sum(t[ok] ** 2 + np.log1p(v[ok] / self.scale[ok] ** 2)))

    def leave_one_out_gaps(self) -> np.ndarray:
        """Total gap of each replica scored against the others, shape (R,)."""
        out = []
        for i in range(self.n_replicas):
            rest = np.delete(self.values, i, axis=0)
            m = NullModel.from_values(self.keys, rest)
            t = (self.values[i] - m.mean) / m.scale
            out.append(total_gap(t, m.df, m.spread_share))
        return np.array(out)

    def leave_one_out_flags(self, alpha: float) -> np.ndarray:
        """Whether each replica, scored against the others, has a location in the gap."""
        out = []
        for i in range(self.n_replicas):
            rest = np.delete(self.values, i, axis=0)
            m = NullModel.from_values(self.keys, rest)
            t = (self.values[i] - m.mean) / m.scale
            out.append(bool(holm(m.p_values(t), alpha).any()))
        return np.array(out)


def build_null(
    replicas: Sequence[Replica], half: str | None, session: Mapping[Key, float] | None = None
) -> NullModel:
    """The null model of one half from replicas.

    Its locations are those every replica has and, when the session's statistics of that
    half are given, the session has too (a location the session lacks cannot be scored).
    """
    keys = set.intersection(*(set(r.stats[half]) for r in replicas))
    if session is not None:
        keys &= set(session)
    keys = sorted(keys, key=str)
    values = np.array(
        [[transform(k, r.stats[half].get(k, np.nan)) for k in keys] for r in replicas]
    )
    return NullModel.from_values(keys, values)


def total_gap(t: np.ndarray, df: int, spread_share: np.ndarray | None = None) -> float:
    """Sum of squared scores beyond its null mean, over the locations that have a score.

    Parameters
    ----------
    t : ndarray, shape (L,)
        Scores (NaN where a location has none).
    df : int
        Degrees of freedom of the scores (> 2).
    spread_share : ndarray, shape (L,), optional
        Per location, the share of its scale that is the replicas' spread
        (:attr:`NullModel.spread_share`); all 1 when omitted.

    Returns
    -------
    float
        ``max(sum t^2 - sum w df / (df - 2), 0)`` over the finite scores, ``w`` the spread
        share: 0 when they add up to no more than noise alone gives on average.
    """
    if df <= 2:
        raise ValueError(f"the gap needs scores with more than 2 degrees of freedom, got {df}")
    t = np.asarray(t, dtype=float)
    ok = np.isfinite(t)
    w = np.ones(t.shape) if spread_share is None else np.asarray(spread_share, dtype=float)
    return float(max(np.sum(t[ok] ** 2) - np.sum(w[ok]) * df / (df - 2), 0.0))


def holm(p: np.ndarray, alpha: float) -> np.ndarray:
    """Holm's step-down rejections at family-wise level ``alpha`` (NaN p never rejected)."""
    p = np.asarray(p, dtype=float)
    ok = np.isfinite(p)
    m = int(ok.sum())
    reject = np.zeros(p.shape, dtype=bool)
    idx = np.where(ok)[0][np.argsort(p[ok])]
    for rank, i in enumerate(idx):
        if p[i] > alpha / (m - rank):
            break
        reject[i] = True
    return reject
