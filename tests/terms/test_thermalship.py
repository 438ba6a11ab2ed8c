"""The temperature terms a pose hold-out ships, in a partial session's calibration, and apply."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from imucal.calibration import ImuCalibration
from imucal.columns import ACC, GYR, MAG, SI_COLUMN_UNITS
from imucal.pipeline.stages import apply_calibration
from imucal.terms import poseholdout as ph
from imucal.terms.thermalship import judge_cell, with_shipped_terms

RATE_HZ, N, NOISE = 1.0, 30_000, 2e-3
SLOPE = np.array([0.0, 4e-4, -2e-4])  # rad/s per K; x has none
SPANS = [(4.8, 16.3), (5.8, 20.1), (5.4, 24.3)]


def _poses(rng: np.random.Generator, flip_pose_2: bool = False) -> list:
    """Three gyro poses with a per-axis linear law and a constant per pose; with
    ``flip_pose_2`` the third pose's y drifts the other way (the law does not carry over)."""
    poses = []
    for k, (lo, hi) in enumerate(SPANS):
        temp = lo + (hi - lo) * np.abs(np.linspace(-1.0, 1.0, N))
        slope = SLOPE.copy()
        if flip_pose_2 and k == 2:
            slope[1] = -slope[1]
        gyr = 1e-3 * k + slope * (temp - 14.0)[:, None] + NOISE * rng.standard_normal((N, 3))
        poses.append(ph.PoseSeries(f"pose_{k}", np.arange(N) / RATE_HZ, temp, {"gyr": gyr}))
    return poses


def _hold_out(poses):
    return ph.hold_out_poses(poses, block_s=600.0, max_order=2, margin_c=1.0, se_block_s=3600.0)


@pytest.fixture(scope="module")
def clean():
    return _hold_out(_poses(np.random.default_rng(5)))


def _partial_calibration(bias: np.ndarray) -> dict:
    gyr = {"bias": bias.tolist(), "matrix": np.eye(3).tolist(), "unit_in": "rad/s",
           "unit_out": "rad/s", "std": {"bias": [1e-4] * 3}, "method": "bias only"}  # fmt: skip
    return {"format_version": 2, "gyr": gyr,
            "missing": {"acc": "no stage of this sensor could run", "mag": "no stage ran"}}  # fmt: skip


def test_a_cell_is_flagged_where_the_term_is_worse_than_none_or_than_a_peer():
    base = {"term_ratio": 0.9, "term_ratio_ci95": [0.8, 1.0], "term_vs_p": 1.0,
            "term_vs_p_ci95": [0.95, 1.05]}  # fmt: skip
    assert judge_cell(base, ["p"], True) == {"flags": [], "flagged": False, "taken": True}
    worse = judge_cell({**base, "term_ratio": 1.02}, ["p"], True)
    assert worse["flagged"] and not worse["taken"] and "worse than no term" in worse["flags"][0]
    beaten = judge_cell({**base, "term_vs_p": 1.1, "term_vs_p_ci95": [1.01, 1.2]}, ["p"], True)
    assert beaten["flags"] == ["p is resolvably better (term / p 1.1000, 1.0100-1.2000)"]
    # within the peer's scatter (interval around 1) is no flag; without a term, a peer that
    # does better is still flagged, and nothing is taken
    assert not judge_cell({**base, "term_vs_p_ci95": [0.99, 1.2]}, ["p"], True)["flagged"]
    none = judge_cell({**base, "term_ratio": 1.0, "term_vs_p_ci95": [1.01, 1.2]}, ["p"], False)
    assert none["flagged"] and not none["taken"]


def test_the_law_that_carries_over_ships_and_one_that_does_not_is_flagged(clean):
    shipped = {e["axis"]: e for e in clean["shipped"]}
    assert not shipped["x"]["taken"]
    for j, axis in ((1, "y"), (2, "z")):
        e = shipped[axis]
        assert e["taken"] and e["order"] == 1
        # block means of 600 samples over three poses: the slope's std from the noise
        assert e["coef"][0] == pytest.approx(SLOPE[j], abs=5 * e["coef_std"][0])
        assert 0.3 * NOISE / np.sqrt(3 * N) / 5.0 < e["coef_std"][0] < 3 * NOISE / np.sqrt(3 * N)
    assert not any(c["flags"] for c in clean["cells"] if c["axis"] != "x")
    flipped = _hold_out(_poses(np.random.default_rng(5), flip_pose_2=True))
    cell = next(c for c in flipped["cells"] if c["axis"] == "y" and c["held_out"] == "pose_2")
    assert cell["flagged"] and not cell["taken"]
    assert not {e["axis"]: e for e in flipped["shipped"]}["y"]["taken"]
    assert any("pose_2 gyr y" in w for w in flipped["warnings"])


def test_the_partial_calibration_carries_the_term_and_apply_uses_it(clean, caplog):
    bias = np.array([0.02, 0.01, -0.03])
    cal = with_shipped_terms(_partial_calibration(bias), clean)
    poly = cal["terms"]["temperature"]["gyr"]
    shipped = {e["axis"]: e for e in clean["shipped"]}
    assert poly["bias"][0][1:] == [shipped["y"]["coef"][0], shipped["z"]["coef"][0]]
    assert poly["bias"][0][0] == 0.0 and poly["bias_std"][0][0] == 0.0
    assert poly["bias_std"][0][1] == shipped["y"]["coef_std"][0]
    assert poly["reference_c"] == shipped["y"]["reference_c"]
    spans = [p["temp_span_c"] for p in clean["poses"]]
    assert poly["span_c"] == [min(lo for lo, _ in spans), max(hi for _, hi in spans)]
    assert cal["temperature_terms"]["gyr x"].startswith("pose_")
    assert cal["temperature_terms"]["gyr y"] == "shipped"
    assert cal["gyr"]["method"] == "bias only; temperature term of y, z (pose hold-out)"
    # the bias moves to the reference temperature by the drift's mean over the poses
    moved = bias - np.array([0.0, shipped["y"]["mean_drift"], shipped["z"]["mean_drift"]])
    np.testing.assert_allclose(cal["gyr"]["bias"], moved, rtol=1e-12)

    calibration = ImuCalibration.from_dict(json.loads(json.dumps(cal)))
    assert calibration.not_calibrated == {"acc": "no stage of this sensor could run",
                                          "mag": "no stage ran"}  # fmt: skip
    rng = np.random.default_rng(1)
    temp = np.linspace(3.0, 26.0, 40)  # beyond the span + margin at both ends
    table = pd.DataFrame(rng.normal(size=(40, 9)), columns=[*ACC, *GYR, *MAG])
    table.insert(0, "t_s", np.arange(40.0))
    table["temp_c"] = temp
    with caplog.at_level("WARNING"):
        out, meta = apply_calibration(table, {"units": SI_COLUMN_UNITS}, calibration, source="r")
    lo, hi = poly["span_c"]
    d_t = np.clip(temp, lo - 1.0, hi + 1.0)[:, None] - poly["reference_c"]
    want = table[list(GYR)].to_numpy() - moved - d_t * np.array(poly["bias"][0])
    np.testing.assert_allclose(out[list(GYR)].to_numpy(), want, rtol=1e-10, atol=1e-15)
    np.testing.assert_array_equal(out[list(ACC)].to_numpy(), table[list(ACC)].to_numpy())
    assert set(meta["not_calibrated"]) == {"acc", "mag"}
    assert meta["temperature_outside_span"]["gyr"]["clamped_fraction"] > 0
    assert "does not calibrate acc" in caplog.text
    assert "outside the gyr calibration's temperature span" in caplog.text
    # and it writes back as it was read: the sensors it does not calibrate stay 'missing'
    back = calibration.to_dict()
    assert "acc" not in back and set(back["missing"]) == {"acc", "mag"}


def test_the_report_section_lists_every_cell_and_the_flags(tmp_path):
    from imucal.report.holdout import holdout_section

    flipped = _hold_out(_poses(np.random.default_rng(5), flip_pose_2=True))
    path = tmp_path / "temperature_holdout.json"
    path.write_text(json.dumps({"recording": "poses", "sensors": ["gyr"], "settings": {},
                                **flipped}))  # fmt: skip
    section = holdout_section(path)
    assert section["peers"] == ["imucal_1", "imucal_2", "cubic"]
    assert len(section["rows"]) == 9 and len(section["summary"]) == 3
    assert all(len(r["rms"]) == 5 and len(r["versus"]) == 3 for r in section["rows"])
    flagged = {(r["pose"], r["axis"]) for r in section["flagged"]}
    assert ("pose_2", "y") in flagged
    row = next(r for r in section["rows"] if (r["pose"], r["axis"]) == ("pose_2", "y"))
    assert row["taken"] == "no"
    assert {e["axis"]: e["taken"] for e in section["shipped"]}["y"] is False
