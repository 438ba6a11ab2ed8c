"""The covariance of calibration.json against the truth of simulated sessions (whole chain)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import z_limit
from scipy import stats

from imucal import errormodel
from imucal.pipeline.full import PipelineOptions, calibrate_session
from imucal.sim import make_truth, simulate_session
from imucal.sim.effects import stream_rng
from imucal.uncertainty import GROUPS

SEEDS = (11, 12, 13)
RANGE_COUNTS = {"acc": 32767, "gyr": 32767, "mag": 32767}


def _session(seed: int):
    truth = make_truth("random", stream_rng(seed, "truth"))
    session = simulate_session(truth, seed)
    imu = {rec: session.si_frame(rec) for rec in session.logs}
    config = session.config
    options = PipelineOptions(
        truth.world.gravity_m_s2,
        session.sensitivity,
        RANGE_COUNTS,
        {"axes": list(config.ratetable_axes), "rates_dps": list(config.rates_dps)},
    )
    return calibrate_session(imu, None, options).calibration, truth.calibration


@pytest.mark.slow
def test_bias_and_matrix_errors_follow_the_reported_covariance():
    """Per sensor and session the Mahalanobis distance of the (bias, matrix) error with the
    reported 12 x 12 covariance is chi-square(12) if the covariance is right; the sum over
    3 sessions x 3 sensors must lie in the 99.9 % interval of chi-square(108). A covariance off
    by a factor 2 in variance moves the sum to ~54 or ~216, outside (about 63 to 160)."""
    total, dof = 0.0, 0
    for seed in SEEDS:
        estimate, truth = _session(seed)
        for sensor in ("acc", "gyr", "mag"):
            est, true = estimate.sensor(sensor), truth.sensor(sensor)
            err = np.r_[est.bias - true.bias, (est.matrix - true.matrix).ravel()]
            total += float(err @ np.linalg.solve(est.covariance[:12, :12], err))
            dof += 12
    low, high = stats.chi2.ppf([0.0005, 0.9995], dof)
    assert low < total < high, (total, low, high)


def test_a_static_of_one_block_has_a_bias_std_and_no_goodness_of_fit():
    from imucal.fits.gyroscope import estimate_bias
    from imucal.pipeline.partial import calibration_of
    from imucal.pipeline.stages import gyr_bias_quality, gyr_bias_value, plain

    rng = np.random.default_rng(3)
    short = plain(estimate_bias(0.01 + 0.003 * rng.standard_normal((500, 3))))  # 5 s at 100 Hz
    assert gyr_bias_quality(short) == {}
    _, std = gyr_bias_value(short, "ls")
    assert np.all(std > 0)
    cal = calibration_of("gyr_bias", {"gyr_bias": short})
    assert "quality" not in cal and np.all(np.asarray(cal["std"]["bias"]) > 0)
    # a long static whose bias wanders: the wander's variance is in the reported std
    walk = np.cumsum(2e-5 * rng.standard_normal((60000, 3)), axis=0)
    wandering = plain(estimate_bias(walk + 0.003 * rng.standard_normal((60000, 3))))
    cal = calibration_of("gyr_bias", {"gyr_bias": wandering})
    assert set(cal["quality"]) == {"bias_x", "bias_y", "bias_z"}
    assert np.all(np.asarray(cal["std"]["bias"]) > 3 * np.asarray(wandering["std_ls_rad_s"]))


def test_tool_free_gyroscope_with_unequal_scales_follows_its_covariance():
    """Eq. 36 with scales 0.95 / 1.2 / 1.05 and 2 deg of misalignment per axis (no
    non-orthogonality, the path's assumption). At unit scale the phases' rates cannot all be
    turned onto their axes: the alignment was off by ~alpha times the scales' spread and the
    scale by ~alpha^2 times it (3e-4, 3-7 std); the alignment at eq. 36's scale leaves
    noise only. Each of scale and alpha within 4 of its reported std (six values: a chance
    of 4e-4 to fail with an honest covariance); alpha's std at the rate noise's level (below
    2e-4 rad: 1.5e-3 rad/s over ~1 rad/s and ~140 independent samples per phase after the 5 Hz
    filter), not 1e-3 (the rate-proportional residuals of a unit-scale alignment)."""
    seed = 2
    truth = make_truth("random", stream_rng(seed, "truth"))
    matrix = errormodel.compose([0.95, 1.2, 1.05], np.zeros(3), np.radians([2.0, -2.0, 2.0]))
    gyr = dataclasses.replace(truth.calibration.gyr, matrix=matrix)
    truth = dataclasses.replace(truth, calibration=dataclasses.replace(truth.calibration, gyr=gyr))
    session = simulate_session(truth, seed)
    imu = {rec: session.si_frame(rec) for rec in session.logs if rec != "ratetable"}
    options = PipelineOptions(
        truth.world.gravity_m_s2, session.sensitivity, RANGE_COUNTS, ratetable=None
    )
    est = calibrate_session(imu, None, options).calibration.gyr
    std = np.sqrt(np.diag(est.covariance))
    got, want = est.decomposition, errormodel.decompose(matrix)
    scale_std, alpha_std = std[GROUPS["scale"]], std[GROUPS["alpha_rad"]]
    z = z_limit(6)  # two-sided over the six at 1e-4
    assert np.all(np.abs(got.scale - want.scale) < z * scale_std), (got.scale, scale_std)
    assert np.all(np.abs(got.alpha_rad - want.alpha_rad) < z * alpha_std), (got.alpha_rad,)
    assert np.all(alpha_std < 2e-4), alpha_std


def test_mean_of_the_acc_and_mag_angles_follows_its_noise(rms_z_band):
    """The two angles of a phase with the variances of the rotation3d pauses (acc 1.5e-8,
    mag 6e-7 rad^2, ratio 40): 4000 draws of the truth plus noise. The mean weighted by the
    noise has the variance 1 / (1 / v_acc + 1 / v_mag); RMS z in the two-sided band of 4000
    draws (0.957-1.044) and the disagreement test inflates at its 0.1 % (at most 0.5 % here). A plain
    mean tested by the same sum inflates 31 % of the draws, its RMS z falls to 0.53."""
    from imucal.pipeline.stages.toolfree import _mean_angle

    rng = np.random.default_rng(4)
    variances = np.array([1.5e-8, 6e-7])
    z, inflated = [], 0
    for _ in range(4000):
        angles = 12.566 + np.sqrt(variances) * rng.standard_normal(2)
        mean, std, weights = _mean_angle(angles, variances)
        assert weights.sum() == pytest.approx(1.0)
        z.append((mean - 12.566) / std)
        inflated += std**2 > 1.0001 / np.sum(1 / variances)
    low, high = rms_z_band(len(z))
    assert low < np.sqrt(np.mean(np.square(z))) < high
    assert inflated <= 20


def test_pause_angle_variance_is_the_scatter_across_the_mean_over_n():
    """Each pause's angle noise is the variance (ddof 1) of its samples' angle from the mean's
    direction over its samples, ``var / n``; the two pauses add; a pause whose halves agree is
    not inflated, one whose halves differ by far more than that noise is."""
    from imucal.pipeline.stages.toolfree import _pause_angle_variance

    rng = np.random.default_rng(5)
    want = 0.0
    pauses = []
    for n, angle in ((40, 0.3), (64, 2.1)):
        phi = angle + 0.01 * rng.standard_normal(n)
        phi[n // 2 :] += phi[: n // 2].mean() - phi[n // 2 :].mean()  # the halves agree
        pause = np.column_stack([rng.normal(0, 1, n), 9.8 * np.cos(phi), 9.8 * np.sin(phi)])
        mean = pause[:, 1:].mean(axis=0)
        across = np.array([-mean[1], mean[0]]) / np.linalg.norm(mean)
        offset = pause[:, 1:] @ across / np.linalg.norm(mean)
        want += np.var(offset, ddof=1) / n
        pauses.append(pause)
    assert _pause_angle_variance(*pauses, "x") == pytest.approx(want, rel=1e-12)
    moved = pauses[0].copy()
    moved[20:, 1:] = moved[20:, 1:] @ np.array([[np.cos(0.05), np.sin(0.05)],
                                                 [-np.sin(0.05), np.cos(0.05)]])  # fmt: skip
    assert _pause_angle_variance(moved, pauses[1], "x") > 10 * want
