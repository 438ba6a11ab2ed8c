"""Temperature terms held out across static poses (imucal.terms.poseholdout)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.signal import lfilter

from imucal.columns import ACC, GYR, TIME
from imucal.io.dataset import read_dataset
from imucal.segments.table import segment_row, segments_frame
from imucal.terms import poseholdout as ph

RATE_HZ = 1.0
POSE_S = 40_000  # about 11 h per pose at 1 Hz
NOISE = 2e-3  # rad/s, white, per sample
BLOCK_S = 600.0
SE_BLOCK_S = 3600.0
#: Per axis: no drift (x), linear (y), quadratic (z), rad/s per K^k about REF_C.
LINEAR = np.array([0.0, 4e-4, -2e-4])
QUADRATIC = np.array([0.0, 0.0, 3e-5])
REF_C = 14.0


def sweep(rng: np.random.Generator, lo: float, hi: float, n: int) -> np.ndarray:
    """A temperature going down from ``hi`` to ``lo`` and back up, with sensor noise (deg C)."""
    u = np.abs(np.linspace(-1.0, 1.0, n))
    return lo + (hi - lo) * u + 0.02 * rng.standard_normal(n)


def drift(temp: np.ndarray) -> np.ndarray:
    d_t = (temp - REF_C)[:, None]
    return LINEAR * d_t + QUADRATIC * d_t**2


def three_poses(
    rng: np.random.Generator, own_slope: np.ndarray = np.zeros((3, 3))
) -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray]:
    """A gyro in three poses with per-axis drift and a constant per pose (g-sensitivity,
    orientation) that grows with the pose's mean temperature, as a pooled regression would read
    as a slope; ``own_slope`` (pose x axis, rad/s per K) adds a drift of one pose's own; 1 Hz.
    Returns the table, its segments and the pose constants (3, 3)."""
    spans = [(4.8, 16.3), (5.8, 20.1), (5.4, 24.3)]
    constants = np.array([[0.0, 0.0, 0.0], [3e-3, 1e-3, -2e-3], [6e-3, -1e-3, 1e-3]])
    parts, rows, start = [], [], 0
    for k, ((lo, hi), c) in enumerate(zip(spans, constants)):
        temp = sweep(rng, lo, hi, POSE_S)
        own = own_slope[k] * (temp - REF_C)[:, None]
        gyr = 0.02 + c + drift(temp) + own + NOISE * rng.standard_normal((POSE_S, 3))
        acc = np.tile(9.81 * np.eye(3)[k], (POSE_S, 1)) + 0.01 * rng.standard_normal((POSE_S, 3))
        parts.append(np.column_stack([acc, gyr, temp]))
        rows.append((f"pose_{k}", start, start + POSE_S))
        start += POSE_S + 100
        parts.append(np.full((100, 7), np.nan))  # handling between poses: no rows of a pose
    data = np.vstack(parts)
    t = np.arange(len(data)) / RATE_HZ
    table = pd.DataFrame({TIME: t, **dict(zip((*ACC, *GYR, "temp_c"), data.T))})
    segments = segments_frame(
        [segment_row("poses", label, "position", t, a, b) for label, a, b in rows]
    )
    return table, segments, constants


@pytest.fixture(scope="module")
def result():
    rng = np.random.default_rng(32)
    table, segments, _ = three_poses(rng)
    return hold_out(table, segments)


def hold_out(table, segments, **settings):
    return ph.hold_out_recording(
        table, segments, recording="poses", **{
            "block_s": BLOCK_S, "settle_s": 0.0, "max_order": 3, "margin_c": 1.0,
            "se_block_s": SE_BLOCK_S, **settings,
        },
    )  # fmt: skip


def cells(result, sensor, axis):
    return [c for c in result["cells"] if c["sensor"] == sensor and c["axis"] == axis]


def test_an_axis_without_drift_gets_no_term(result):
    for c in cells(result, "gyr", "x"):
        assert c["order"] == 0, c["inner_rms"]
        assert c["rms_term"] == c["rms_none"]
        # white noise alone: the held-out RMS is the noise (its sampling error ~ 1/sqrt(2n))
        assert c["rms_none"] == pytest.approx(NOISE, rel=5 / np.sqrt(2 * c["samples"]))
    # nothing carries over, so nothing ships
    shipped = {(e["sensor"], e["axis"]): e for e in result["shipped"]}
    assert not shipped[("gyr", "x")]["taken"]


def test_drifting_axes_get_their_order_and_coefficients(result):
    """Each held-out pose's order, chosen on the two fit poses alone, is the drift's."""
    for axis, truth in (("y", [LINEAR[1]]), ("z", [LINEAR[2], QUADRATIC[2]])):
        for c in cells(result, "gyr", axis):
            assert c["order"] == len(truth), (c["held_out"], c["inner_rms"])
            # the fit is about its own reference temperature: move the truth there
            shift = c["reference_c"] - REF_C
            expected = (
                [truth[0]] if len(truth) == 1 else [truth[0] + 2 * truth[1] * shift, truth[1]]
            )
            # block means of 600 samples over two poses; the slope's std from the noise
            n_blocks = 2 * POSE_S / BLOCK_S
            slope_std = NOISE / np.sqrt(BLOCK_S) / np.sqrt(n_blocks) / 5.0  # temp std ~5 K
            assert c["coef"][0] == pytest.approx(expected[0], abs=5 * slope_std)
            if len(truth) == 2:
                assert c["coef"][1] == pytest.approx(expected[1], abs=5 * slope_std / 5.0)
            # the term leaves the white noise: its held-out RMS is the noise's
            assert c["rms_term"] == pytest.approx(NOISE, rel=5 / np.sqrt(2 * c["samples"]))
            assert c["rms_term"] < c["rms_none"]
            best_peer = min(c[f"rms_{m}"] for m in result["methods"] if m not in ("none", "term"))
            assert c["rms_term"] <= best_peer * (1 + 5 / np.sqrt(2 * c["samples"]))
            assert "worse" not in c["verdicts"].values()
            assert c["taken"] and not c["flags"], c["flags"]


def test_the_held_out_pose_is_compared_within_the_fit_span(result):
    poses = {p["label"]: p for p in result["poses"]}
    for c in result["cells"]:
        others = [p for label, p in poses.items() if label != c["held_out"]]
        hi = max(p["temp_span_c"][1] for p in others) + result["settings"]["margin_c"]
        own = poses[c["held_out"]]["temp_span_c"]
        assert c["fraction"] == 1.0 if own[1] <= hi else c["fraction"] < 1.0


def test_the_held_out_pose_takes_no_part_in_its_own_order():
    """Pose 2 drifts on y against its temperature by a slope of its own, opposite to the law of
    the part: a polynomial fitted with it predicts no other pose, but held out it is predicted
    by the law found on poses 0 and 1, as if it did not drift (its order and coefficients are
    the same to the last digit: its samples take no part in them)."""
    own = np.zeros((3, 3))
    own[2, 1] = -3.0 * LINEAR[1]
    runs = [hold_out(*three_poses(np.random.default_rng(7), slope)[:2]) for slope in (0 * own, own)]
    clean, drifting = ({c["held_out"]: c for c in cells(r, "gyr", "y")} for r in runs)
    assert drifting["pose_2"]["order"] == clean["pose_2"]["order"] == 1
    assert drifting["pose_2"]["coef"] == clean["pose_2"]["coef"]
    slope_std = NOISE / np.sqrt(BLOCK_S) / np.sqrt(2 * POSE_S / BLOCK_S) / 5.0
    assert drifting["pose_2"]["coef"][0] == pytest.approx(LINEAR[1], abs=5 * slope_std)
    # the law does not hold on pose 2, and the table says so: the cell is flagged, its term
    # not taken, and the axis ships no term; the clean run takes and ships it
    assert drifting["pose_2"]["term_ratio_ci95"][0] > 1.0
    assert drifting["pose_2"]["flagged"] and not drifting["pose_2"]["taken"]
    assert "worse than no term" in drifting["pose_2"]["flags"][0]
    assert not clean["pose_2"]["flags"] and clean["pose_2"]["taken"]
    shipped = [{(e["sensor"], e["axis"]): e for e in r["shipped"]} for r in runs]
    assert shipped[0][("gyr", "y")]["taken"]
    assert not shipped[1][("gyr", "y")]["taken"]
    assert "pose_2: the term is worse than no term" in shipped[1][("gyr", "y")]["reason"]


#: A pose's own drift: a random walk pulled back over this time (s), of this std (rad/s).
DRIFT_TAU_S, DRIFT_STD = 600.0, 2e-3


def drifting_poses(rng: np.random.Generator, n: int, step: float = 0.0) -> list:
    """Three gyro poses of ``n`` samples with no law of temperature: each a drift of its own
    (:data:`DRIFT_TAU_S`, :data:`DRIFT_STD`) and white noise, its level ``step * k`` (rad/s)."""
    phi = np.exp(-1.0 / DRIFT_TAU_S)
    poses = []
    for k, (lo, hi) in enumerate([(4.8, 16.3), (5.8, 20.1), (5.4, 24.3)]):
        temp = sweep(rng, lo, hi, n)
        kick = DRIFT_STD * np.sqrt(1 - phi**2) * rng.standard_normal((n, 3))
        gyr = lfilter([1.0], [1.0, -phi], kick, axis=0) + NOISE * rng.standard_normal((n, 3))
        poses.append(
            ph.PoseSeries(f"pose_{k}", np.arange(n) / RATE_HZ, temp, {"gyr": gyr + step * k})
        )
    return poses


def test_the_uncertainty_follows_correlated_residuals():
    """A drift of its own in every pose (a random walk pulled back over DRIFT_TAU_S, not a
    function of temperature): the standard error of the held-out RMS over long blocks matches
    the spread over independent realisations, where the white-noise formula is far too
    small."""
    n, runs = 20_000, 24
    rms, se = [], []
    for seed in range(runs):
        poses = drifting_poses(np.random.default_rng(100 + seed), n)
        out = ph.hold_out_poses(
            poses, block_s=BLOCK_S, max_order=1, margin_c=1.0, se_block_s=6 * DRIFT_TAU_S
        )
        cell = next(c for c in out["cells"] if c["held_out"] == "pose_0" and c["axis"] == "x")
        rms.append(cell["rms_none"])
        se.append(cell["rms_none_se"])
    spread = np.std(rms, ddof=1)
    # the spread of 24 realisations is known to about 1 / sqrt(2 * 23) = 15 %; the standard
    # error over about 6 blocks of 6 tau per pose is a little low (0.86 of the spread here)
    assert 0.55 * spread < np.mean(se) < 1.45 * spread
    assert np.mean(rms) / np.sqrt(2 * n) < 0.3 * spread


@pytest.mark.parametrize("step", [0.0, 1e-2])
def test_the_interval_of_a_ratio_holds_the_fits_scatter(step):
    """Three poses with no law of temperature, each with a drift of its own correlated over
    DRIFT_TAU_S: the slope IMUcalibrate fits on one pose is noise, and so is its gain or loss
    against the term on the third. With ``step`` (rad/s) the poses' levels step up from pose
    to pose (each method has a constant per pose, so nothing changes but the data). Over
    independent realisations the interval of term / IMUcalibrate with the fits' scatter
    covers the centre of the log ratios close to 95 % of the time without being much wider
    than their spread requires; the interval given the fits (the held-out samples' noise
    alone) covers less."""
    n, runs = 20_000, 60
    ratio, with_fits, given_fits = [], [], []
    for seed in range(runs):
        poses = drifting_poses(np.random.default_rng(500 + seed), n, step)
        out = ph.hold_out_poses(
            poses, block_s=BLOCK_S, max_order=1, margin_c=1.0, se_block_s=6 * DRIFT_TAU_S
        )
        for c in out["cells"]:
            if c["held_out"] == "pose_0":
                ratio.append(np.log(c["term_vs_imucal_1"]))
                with_fits.append(np.log(c["term_vs_imucal_1_ci95"]))
                given_fits.append(np.log(c["term_vs_imucal_1_ci95_given_fits"]))
    centre, spread = np.mean(ratio), np.std(ratio, ddof=1)

    def coverage(intervals):
        return np.mean([lo <= centre <= hi for lo, hi in intervals])

    # 180 cells: a coverage of 0.9 is measured to about +-0.022 (one binomial standard
    # deviation); a 95 % half-width is about 2.2 spreads (Student's t, about 10 dof)
    assert coverage(with_fits) >= 0.85
    assert np.median(np.diff(with_fits, axis=1)) / 2 < 3.0 * spread
    if step == 0.0:
        assert coverage(given_fits) < 0.90


def test_fewer_than_three_poses_are_refused():
    rng = np.random.default_rng(1)
    table, segments, _ = three_poses(rng)
    with pytest.raises(ValueError, match=r"2 static pose\(s\) with samples; holding one out needs"):
        hold_out(table, segments.iloc[:2], max_order=2)


def test_the_recording_with_declared_poses_and_a_temperature_channel(tmp_path):
    entry = {"reader": "table", "file": "x.csv", "rate_hz": 1.0, "units": {"gyr": "rad/s"},
             "columns": {"gyr_x": "a", "gyr_y": "b", "gyr_z": "c", "temp_c": "t"}}  # fmt: skip
    poses = [{"recording": "poses", "label": f"p{k}", "kind": "position", "start_s": 10.0 * k,
              "end_s": 10.0 * k + 5} for k in range(3)]  # fmt: skip
    cfg = {"name": "t", "gravity_m_s2": 9.81, "recordings": {"poses": entry}, "segments": poses}
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(cfg))
    assert ph.holdout_recording(read_dataset(tmp_path)) == "poses"
    cfg["segments"] = poses[:2]
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(cfg))
    assert ph.holdout_recording(read_dataset(tmp_path)) is None


REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
CATS = Path(__file__).resolve().parents[2] / "data" / "real" / "spluque_cats_thermal"


def test_cats_tag_held_out_across_its_three_poses():
    """Each held-out pose's order is chosen on the two others alone: gyro x (whose slope
    within a pose changes sign from pose to pose) gets no term, gyro y its slope (about 0.45
    mrad/s per K, SOURCE.md: +0.026 deg/s per K). Every cell whose term is taken is no worse
    than none and within the scatter of every peer; the magnetometer's y, where a polynomial
    fitted on two poses does not carry over to the third, is flagged and ships no term."""
    if not (REAL / "spluque__scikit-diveMove" / "cats_temperature_calib.nc").is_file():
        pytest.skip(f"the CATS recording is not at {REAL} (../shared is absent)")
    from imucal.ingest import ingest_recording
    from imucal.segments.segmentation import segment_dataset

    dataset = read_dataset(CATS)
    table, _ = ingest_recording(dataset.recordings["poses"], "poses", dataset, "test")
    segments = segment_dataset({"poses": table}, manual=dataset.segments)
    out = ph.hold_out_recording(
        table, segments, recording="poses", block_s=600.0, settle_s=3600.0, max_order=3,
        margin_c=1.0, se_block_s=14400.0,
    )  # fmt: skip
    order = {(o["sensor"], o["axis"]): o["by_pose"] for o in out["orders"]}
    assert set(order[("gyr", "x")].values()) == {0}
    assert min(order[("gyr", "y")].values()) >= 1
    peers = [m for m in out["methods"] if m not in ("none", "term")]
    for c in out["cells"] + out["summary"]:
        if c["taken"]:
            assert c["term_ratio"] <= 1.0, c
            assert all(c[f"term_vs_{p}_ci95"][0] <= 1.0 for p in peers), c
        else:
            assert c["flags"] or c.get("order", 1) == 0 or not c["taken"]
    mag_y = {c["held_out"]: c for c in cells(out, "mag", "y")}
    assert mag_y["pose_x"]["order"] == 2 and mag_y["pose_x"]["flagged"]
    assert mag_y["pose_x"]["term_ratio_ci95"][0] > 1.0  # worse than no term, resolvably
    shipped = {(e["sensor"], e["axis"]): e for e in out["shipped"]}
    assert not shipped[("mag", "y")]["taken"] and not shipped[("gyr", "x")]["taken"]
    assert shipped[("gyr", "y")]["taken"]
    gyr_y = shipped[("gyr", "y")]
    assert gyr_y["coef"][0] == pytest.approx(0.026 * np.pi / 180, rel=0.2)
    assert gyr_y["coef_std"][0] < 0.1 * gyr_y["coef"][0]


def test_poses_with_fewer_than_three_standard_error_blocks_are_warned():
    rng = np.random.default_rng(3)
    n = 10_000  # 2.8 h at 1 Hz: one block of 4 h
    poses = [
        ph.PoseSeries(
            f"pose_{k}", np.arange(n) / RATE_HZ, sweep(rng, 5.0, 15.0 + 3 * k, n),
            {"gyr": NOISE * rng.standard_normal((n, 3))},
        )
        for k in range(3)
    ]  # fmt: skip
    out = ph.hold_out_poses(poses, block_s=BLOCK_S, max_order=1, margin_c=1.0, se_block_s=14_400)
    assert len(out["warnings"]) == 3
    assert "1 block(s) of se_block_s (14400 s): no spread over blocks" in out["warnings"][0]
    out = ph.hold_out_poses(poses, block_s=BLOCK_S, max_order=1, margin_c=1.0, se_block_s=4800)
    assert "3 block(s)" not in " ".join(out["warnings"])
    out = ph.hold_out_poses(poses, block_s=BLOCK_S, max_order=1, margin_c=1.0, se_block_s=6000)
    assert (
        "2 block(s) of se_block_s (6000 s): its standard errors rest on one" in out["warnings"][0]
    )
    with pytest.raises(ValueError, match="must be a whole number of block_s"):
        ph.hold_out_poses(poses, block_s=BLOCK_S, max_order=1, margin_c=1.0, se_block_s=1000.0)


def test_a_pose_that_barely_overlaps_the_others_span_does_not_veto_an_order():
    """Four poses with one linear law; the hottest pose overlaps the span of the others only
    at the start of its hold, in one block: predicted from them it has no standard error, so
    it neither confirms nor refutes the order, and the two other fit poses decide."""
    rng = np.random.default_rng(11)
    n, slope = 20_000, 4e-4
    spans = [(5.0, 13.0), (8.0, 16.0), (11.0, 19.0), (19.5, 27.0)]
    poses = []
    for k, (lo, hi) in enumerate(spans):
        temp = lo + (hi - lo) * np.sqrt(np.linspace(0.0, 1.0, n))  # warming, fast at first
        gyr = slope * (temp - 14.0)[:, None] + NOISE * rng.standard_normal((n, 3)) + 1e-3 * k
        poses.append(ph.PoseSeries(f"pose_{k}", np.arange(n) / RATE_HZ, temp, {"gyr": gyr}))
    out = ph.hold_out_poses(poses, block_s=BLOCK_S, max_order=1, margin_c=1.0, se_block_s=3600.0)
    orders = [c["order"] for c in out["cells"] if c["held_out"] == "pose_1"]
    assert orders == [1, 1, 1]
