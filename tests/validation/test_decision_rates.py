"""Decision rules of the validation: the plausibility verdicts, the fit-against-fallback choice
and the paired comparison of two gyroscopes' window errors.

Each verdict is read with the standard deviation of its own parameter (every parameter gets a
std of its own here, so reading another's changes the verdict), and its false-alarm rate and
power are counted over draws of known truth and must fall in the Binomial band that holds the
count with probability 1 - 1e-4 (``binomial_band``). The rates are in docs/testing.md.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from imucal import errormodel
from imucal.validation.orientation import compare_window_errors
from imucal.validation.plausibility import (
    BOUNDS,
    CONFIDENT_SIGMA,
    check_bounds,
    compare_with_fallback,
    review_fit,
)

#: Parameter -> the entry of the upper-triangular matrix its std is read from (eq. 6:
#: ``U = T_N S``, row 0 ``(s_x, xi_z s_y, -xi_y s_z)``, row 1 ``(0, s_y, xi_x s_z)``).
ENTRY = {
    "scale x": (0, 0),
    "scale y": (1, 1),
    "scale z": (2, 2),
    "xi_x": (1, 2),
    "xi_y": (0, 2),
    "xi_z": (0, 1),
}


def _outside(sensor: str, name: str) -> tuple[np.ndarray, float]:
    """A matrix with parameter ``name`` just outside its bound, and by how much (its unit)."""
    bounds = BOUNDS[sensor]
    scale, xi = np.ones(3), np.zeros(3)
    if name.startswith("scale"):
        k = "xyz".index(name[-1])
        scale[k] = bounds.scale[1] + 0.04
        if bounds.relative:  # relative to the geometric mean of the three
            scale[k] = (bounds.scale[1] + 0.04) ** 1.5
        return errormodel.compose(scale, xi, np.zeros(3)), 0.04
    xi["xyz".index(name[-1])] = np.radians(bounds.nonorthogonality_deg + 0.6)
    return errormodel.compose(scale, xi, np.zeros(3)), 0.6


def _std_matrix(own: tuple[int, int], own_std: float, upper: np.ndarray) -> np.ndarray:
    """Every other entry an std that decides nothing on its own (its interval narrower than the
    range), the entry ``own`` its own."""
    std = np.where(np.eye(3, dtype=bool), 0.03, np.radians(0.4)) * np.triu(np.ones((3, 3)))
    std[own] = own_std
    return std


@pytest.mark.parametrize("sensor", ["gyr", "acc", "mag"])
@pytest.mark.parametrize("name", list(ENTRY))
def test_each_verdict_reads_the_std_of_its_own_parameter(sensor, name):
    """Outside its bound by ``d``: implausible with its own std below ``d / 3``, undetermined
    above it; the other parameters, within their bounds, add nothing."""
    matrix, d = _outside(sensor, name)
    _, upper = errormodel.upper_triangular_factor(matrix)
    unit = 1.0 if name.startswith("scale") else np.radians(1.0) * np.mean(np.diag(upper))
    if name.startswith("scale") and BOUNDS[sensor].relative:
        unit = float(np.exp(np.mean(np.log(np.diag(upper)))))
    for factor, verdict in ((0.5, "implausible"), (2.0, "undetermined")):
        own = factor * d / CONFIDENT_SIGMA * unit
        out = check_bounds(sensor, matrix, _std_matrix(ENTRY[name], own, upper))
        other = "undetermined" if verdict == "implausible" else "implausible"
        assert len(out[verdict]) == 1 and not out[other], (factor, out)
        assert name in out[verdict][0]


def test_implausible_false_alarm_at_the_bound_and_power_beyond_it(binomial_band):
    """A gyro scale whose truth is the upper bound, estimated with std 0.01: called implausible
    in ``P(z > 3)`` = 0.00135 of 1500 draws; a truth 5 std beyond it in ``P(z > -2)`` =
    0.977; and the boundary itself: 3 std out is not yet implausible, a hair beyond is."""
    rng = np.random.default_rng(7)
    high = BOUNDS["gyr"].scale[1]
    std = np.diag([0.01, 0.0, 0.0])
    draws = 1500
    edge = np.diag([2.0**-6, 0.0, 0.0])  # exact in binary, so is the bound plus 3 of it
    at = high + CONFIDENT_SIGMA * 2.0**-6
    assert not check_bounds("gyr", np.diag([at, 1, 1]), edge)["implausible"]
    assert check_bounds("gyr", np.diag([at + 1e-9, 1, 1]), edge)["implausible"]
    for truth, p in ((high, stats.norm.sf(CONFIDENT_SIGMA)), (high + 0.05, stats.norm.sf(-2))):
        values = truth + 0.01 * rng.standard_normal(draws)
        hits = sum(
            bool(check_bounds("gyr", np.diag([v, 1, 1]), std)["implausible"]) for v in values
        )
        low, top = binomial_band(draws, p)
        assert low <= hits <= top, (truth, hits, low, top)


def _windows(errors: np.ndarray) -> list[dict]:
    return [{"10s": (np.arange(errors.size, dtype=float), errors)}]


def test_fit_against_fallback_refusal_rates(binomial_band):
    """A fit as good as its fallback (window errors of one distribution, 40 windows each) is
    called worse when its median or its RMS is larger: 0.641 of the draws (measured with the
    rule on 100000 draws of another seed); a fit whose errors are 0.7 of the fallback's is
    called worse in 0.089 of them."""
    rng = np.random.default_rng(8)
    draws = 4000
    for ratio, p in ((1.0, 0.641), (0.7, 0.089)):
        worse = 0
        for _ in range(draws):
            base = np.abs(rng.standard_normal((2, 40)))
            worse += compare_with_fallback(_windows(ratio * base[0]), _windows(base[1]))["worse"]
        low, high = binomial_band(draws, p)
        assert low <= worse <= high, (ratio, worse, low, high)


def test_fit_against_fallback_is_median_or_rms():
    a = np.array([1.0, 1.0, 1.0, 1.0, 10.0])
    b = np.array([2.0, 2.0, 2.0, 2.0, 2.0])
    out = compare_with_fallback(_windows(a), _windows(b))
    assert out["worse"] and out["fitted"]["rms_deg"] == pytest.approx(np.sqrt(104 / 5))
    assert out["fitted"]["median_deg"] == 1.0 and out["n"] == 5
    assert not compare_with_fallback(_windows(a[:4]), _windows(b[:4]))["worse"]
    assert compare_with_fallback(_windows(b[:0]), _windows(b))["worse"] is None


def test_heldout_refusal_is_rms_after_against_before():
    art = {"heldout_error_before_m_s2": [0.1, -0.1, 0.1], "heldout_error_after_m_s2": [0.1] * 3}
    assert review_fit("acc", {"matrix": np.eye(3).tolist()}, art)["refuse"] == []
    art["heldout_error_after_m_s2"] = [0.1, 0.1, -0.10001]
    assert len(review_fit("acc", {"matrix": np.eye(3).tolist()}, art)["refuse"]) == 1


def test_window_comparison_takes_windows_that_share_no_span():
    """Windows of 1 s started every 0.25 s: the paired test takes one each second, at the
    starts both gyroscopes have."""
    starts = np.arange(0.0, 30.0, 0.25)
    rng = np.random.default_rng(9)
    a, b = np.abs(rng.standard_normal(starts.size)), np.abs(rng.standard_normal(starts.size))
    out = compare_window_errors((starts, a), (starts, b), 1.0)
    assert out["n_windows"] == 30
    chosen = starts[::4]
    want = stats.wilcoxon(a[::4] - b[::4]).pvalue
    assert out["p_value"] == pytest.approx(want, rel=1e-12) and chosen.size == 30
    # only the starts both have: every other one missing from the baseline
    out = compare_window_errors((starts, a), (starts[::2], b[::2]), 1.0)
    assert out["n_windows"] == 30


def test_window_comparison_false_alarm_and_power(binomial_band):
    """Two gyroscopes with errors of one distribution differ at 5 % in 5 % of 1000 draws (the
    signed-rank test is exact at 30 pairs: 0.048, the size of its discrete critical region,
    measured on 20000 draws of another seed); one with errors 0.5 deg larger is called worse
    in 0.876 of them (the same measurement)."""
    rng = np.random.default_rng(10)
    starts = np.arange(30.0)
    draws = 1000
    for shift, p in ((0.0, 0.048), (0.5, 0.876)):
        verdicts = []
        for _ in range(draws):
            e = np.abs(rng.standard_normal((2, 30)))
            verdicts.append(compare_window_errors((starts, e[0] + shift), (starts, e[1]), 1.0))
        called = sum(v["verdict"] != "no significant difference" for v in verdicts)
        low, high = binomial_band(draws, p)
        assert low <= called <= high, (shift, called, low, high)


def test_mounting_std_is_the_inverse_information_of_the_weighted_pairs():
    """``cov = (sum_s w_s sum_i (|v_i|^2 I - v_i v_i^T))^-1``, ``w_s`` the inverse of the
    sensor's residual variance per component, ``v = R r``; ``angle_std_deg`` is
    ``sqrt(trace(cov))`` in degrees."""
    from scipy.spatial.transform import Rotation

    from imucal.validation.mounting import estimate_mounting

    rng = np.random.default_rng(12)
    rot = Rotation.from_rotvec([0.02, -0.3, 0.1])
    ref = {"acc": rng.normal(0, 9.8, (200, 3)), "gyr": rng.normal(0, 1.0, (300, 3))}
    noise = {"acc": 0.05, "gyr": 0.004}
    module = {s: rot.apply(v) + noise[s] * rng.standard_normal(v.shape) for s, v in ref.items()}
    out = estimate_mounting(module, ref)
    info = np.zeros((3, 3))
    for s, r in ref.items():
        v = r @ out.matrix.T
        w = 1.0 / np.mean((module[s] - v) ** 2)
        assert out.residual_rms[s] == pytest.approx(np.sqrt(1 / w), rel=1e-12)
        info += w * (np.sum(v * v) * np.eye(3) - v.T @ v)
    want = np.degrees(np.sqrt(np.trace(np.linalg.inv(info))))
    assert out.angle_std_deg == pytest.approx(want, rel=1e-10)
