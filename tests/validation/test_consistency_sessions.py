"""The check of the shipped standard deviations on simulated sessions: with white noise alone the
parts' RMS z over many seeds lies in its chi-square band; a model error beyond the noise (a
wandering gyroscope bias, a hand that holds the module for less than a second) ends with
inflated standard deviations or a warning."""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import partial_session

from imucal.calibration import SensorCalibration
from imucal.pipeline import partial
from imucal.pipeline.parts import check_partial_session
from imucal.segments.segmentation import segment_dataset
from imucal.sim import ProtocolConfig, make_effect, make_truth, simulate_session
from imucal.sim.effects import stream_rng
from imucal.sim.protocol import TumbleConfig
from imucal.sim.tumble import simulate_tumble
from imucal.validation.consistency import RMS_Z_LIMIT, ship

pytestmark = pytest.mark.slow


def run_and_check(tables: dict, **segmentation) -> tuple[dict, dict]:
    """The partial path on a simulated session, and the check of what it ships."""
    segments = segment_dataset(tables, fallback=True, **segmentation)
    # the partial path's settings of a simulated session (SI tables, ranges unknown)
    session = partial_session(tables, segments, notes=segments.attrs["notes"])
    outcomes = partial.run_stages(session)
    final = partial.final_calibration(outcomes, session.options)
    calibration = {s: e["calibration"] for s, e in final["sensors"].items()}
    listing = [o.summary() for o in outcomes]
    artifacts = {o.name: o.artifact for o in outcomes if o.status == "run"}
    check = check_partial_session(session, listing, calibration, artifacts)
    return calibration, check


#: Seeds of the white-noise sessions.
WHITE_SEEDS = range(8)


@pytest.fixture(scope="module")
def white_checks():
    """A module tumbled through 26 poses held 2-3 s each on a table-like rest (white noise,
    no effect): the magnetometer's ellipsoid, the cube fit and pose to pose, cut in halves."""
    checks = []
    for seed in WHITE_SEEDS:
        truth = make_truth("random", stream_rng(seed, "truth"))
        session = simulate_tumble(truth, seed, TumbleConfig(hold_s=(2.0, 3.0)))
        checks.append(run_and_check({"poses": session.si_frame()})[1])
    return checks


def test_white_noise_parts_give_rms_z_in_the_chi_square_band(white_checks, rms_z_band):
    stages = {"mag": "mag_step1", "acc": "acc_cube", "gyr": "gyr_pose_to_pose"}
    for sensor, stage in stages.items():
        for group in ("bias", "matrix"):
            chi2 = dof = 0
            for check in white_checks:
                entry = check["sensors"][sensor]
                assert entry["stage"] == stage and entry["parts"]["scheme"] == "halves"
                found = entry["parts"]["groups"][group]
                chi2 += found["rank"] * found["rms_z"] ** 2
                dof += found["rank"]
            low, high = rms_z_band(dof)
            assert low <= np.sqrt(chi2 / dof) <= high, (sensor, group, np.sqrt(chi2 / dof), dof)


def test_white_noise_parts_rarely_inflate_and_more_rarely_warn(white_checks):
    # a sensor over the limit by chance: its bias (chi2(3) > 3 * 1.5^2, probability 0.08),
    # matrix (chi2(6) or chi2(9): 0.036, 0.016) or both together (0.01): about 0.13 of the
    # sensors, 3.2 of 24 expected, 9 or more with probability 3e-3 (binomial); a warning only
    # beyond chance at 1 % (bias, matrix, together, three derived groups, the poses left out): at
    # most about 0.05 of them, 5 or more with probability below 0.01
    entries = [entry for check in white_checks for entry in check["sensors"].values()]
    inflated = sum(max(entry["inflation"].values()) > 1.0 for entry in entries)
    warned = sum(bool(entry["warnings"]) for entry in entries)
    assert inflated < 9 and warned < 5, (inflated, warned)


def test_a_wandering_gyroscope_bias_is_inflated_and_warned():
    # a warm-up drifts the gyroscope's bias through the static recording: its halves differ by
    # far more than the noise of either, which the recording's 10-s blocks do not all show
    truth = make_truth("random", stream_rng(5, "truth"))
    drift = make_effect("temperature_drift", acc_per_k=0.0, acc_scale_per_k=0.0,
                        gyr_scale_per_k=0.0)  # fmt: skip
    session = simulate_session(truth, 5, ProtocolConfig(static_s=300.0), (drift,))
    calibration, check = run_and_check({"static": session.si_frame("static")})
    entry = check["sensors"]["gyr"]
    assert entry["stage"] == "gyr_bias" and entry["parts"]["scheme"] == "halves"
    assert entry["inflation"]["bias"] > RMS_Z_LIMIT
    assert any("its bias differs between two independent parts" in w for w in entry["warnings"])
    shipped = ship(calibration, check)["gyr"]
    ratio = np.asarray(shipped["std"]["bias"]) / np.asarray(calibration["gyr"]["std"]["bias"])
    np.testing.assert_allclose(ratio, entry["inflation"]["bias"])


def _upper(matrix: np.ndarray) -> np.ndarray:
    """The upper-triangular factor (positive diagonal) the cube fit estimates: ``matrix = Q R``."""
    _, r = np.linalg.qr(matrix)
    return np.sign(np.diag(r))[:, None] * r


#: The refusal's hint (imucal.segments.segmentation.orientation_note): the setting and value.
HINT = re.compile(r"segmentation\.min_static_s: ([0-9.]+) and segmentation\.window_s: ([0-9.]+)")


@pytest.mark.parametrize("seed", [1, 2, 4])
def test_a_hand_tumbled_session_ends_with_an_inflated_std_or_a_warning(seed):
    # 26 pauses of 0.5-0.9 s by hand, fast turns between them: the hand turns and moves the
    # module by millimetres through every pause (a lever arm of 12 cm to the wrist), so each
    # pause's mean is off the sphere |a| = g by more than its noise says; segmented with the
    # min_static_s the refusal at the defaults names, as a user would
    truth = make_truth("mems", stream_rng(seed, "truth"))
    hand = (
        make_effect("hand_tremor", sway_mm=8.0),
        make_effect("lever_arm", x_m=0.1, y_m=0.05, z_m=0.03),
    )
    tables = {
        "poses": simulate_tumble(truth, seed, TumbleConfig(move_s=(0.4, 0.8)), hand).si_frame()
    }
    hint = HINT.search(segment_dataset(tables, fallback=True).attrs["notes"]["poses"])
    settings = {"min_static_s": float(hint.group(1)), "window_s": float(hint.group(2))}
    calibration, check = run_and_check(tables, **settings)
    acc = check["sensors"]["acc"]
    assert acc["stage"] == "acc_cube"
    shipped = SensorCalibration.from_dict("acc", ship(calibration, check)["acc"])
    inflated = [q["inflation"] for q in shipped.quality.values() if "inflation" in q]
    assert max(inflated) > 1.0 or acc["warnings"], (inflated, acc)
    # the shipped accelerometer within 3 of its standard deviations of the truth, or warned
    true = truth.calibration.sensor("acc")
    std = np.sqrt(np.diag(shipped.covariance))[:12]
    error = np.r_[shipped.bias - true.bias, (shipped.matrix - _upper(true.matrix)).ravel()]
    z = np.abs(error[std > 0] / std[std > 0])
    assert z.max() <= 3.0 or acc["warnings"], z
