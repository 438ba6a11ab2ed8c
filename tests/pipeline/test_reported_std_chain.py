"""The standard deviations of calibration.json against the errors of simulated sessions.

The sessions are those of ``tests/benchmarks/mc_uncertainty.py`` (the long sweep, kept as a
benchmark: ``snakemake --cores 1 uncertainty_benchmark``), fewer of them: the whole chain in
process, with and without the rate table, and the partial paths. Each parameter group's RMS z
(error over the reported std, pooled over the three axes) must lie in the interval that holds
the RMS of that many standard normal draws with probability 1 - 1e-4 over all the groups of
a test (``rms_z_band``). The draws of one session are not all independent (a shared truth and
noise), so the interval is a little narrow for the pooled groups; a std off by a factor 2
falls outside it in every group.
"""

from __future__ import annotations

import functools
import importlib.util
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import z_limit

from imucal.columns import ACC, MAG
from imucal.pipeline.full import calibrate_session
from imucal.pipeline.stages.toolfree import _phase_angles
from imucal.segments.segmentation import segment_dataset
from imucal.sim import make_truth, simulate_session
from imucal.sim.effects import stream_rng
from imucal.uncertainty import GROUPS

BENCHMARK = Path(__file__).resolve().parents[1] / "benchmarks" / "mc_uncertainty.py"


@functools.cache
def _benchmark():
    spec = importlib.util.spec_from_file_location("mc_uncertainty", BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def _z(records: list[dict]) -> dict[tuple[str, str], np.ndarray]:
    """(path, sensor) -> z per session and parameter, shape (n, 21); NaN where no std."""
    out = {}
    for r in records:
        est, truth, std = (np.asarray(r[k], dtype=float) for k in ("estimate", "truth", "std"))
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(std > 0, (est - truth) / std, np.nan)
        out.setdefault((r["path"], r["sensor"]), []).append(z)
    return {k: np.array(v) for k, v in out.items()}


def _check(z: dict, groups: dict[tuple[str, str], tuple[str, ...]], band) -> None:
    checks = []
    for key, names in groups.items():
        for group in names:
            values = z[key][:, GROUPS[group]]
            checks.append((key, group, values[np.isfinite(values)]))
    failed = []
    for key, group, values in checks:
        low, high = band(values.size, 1e-4 / len(checks))
        rms = float(np.sqrt(np.mean(values**2)))
        if not low < rms < high:
            failed.append(
                f"{key} {group}: RMS z {rms:.2f} of {values.size}, [{low:.2f}, {high:.2f}]"
            )
    assert not failed, failed


@pytest.mark.slow
def test_tool_free_gyroscope_reports_the_std_of_its_errors(rms_z_band):
    """16 sessions without the rate table (eq. 36; the truth's gyroscope xi zero, the path's
    assumption): bias, scale and alpha. The z-scale's std is mostly the magnetometer's angle
    noise (one sensor, the field's projection ~0.5): without that term it is 4 times too
    small."""
    mc = _benchmark()
    records = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in range(100, 116):
            records += mc.run_partial(seed, "platform", ())
    z = _z(records)
    _check(
        z,
        {
            ("gyr_scale", "gyr"): ("bias", "scale", "alpha_rad"),
            ("mag_step2", "mag"): ("bias", "scale", "xi_rad", "alpha_rad"),
        },
        rms_z_band,
    )
    # per axis too: the z-scale must not hide in the pooled group
    low, high = rms_z_band(16, 1e-4)
    rms = np.sqrt(np.mean(z[("gyr_scale", "gyr")][:, GROUPS["scale"]] ** 2, axis=0))
    assert np.all((low < rms) & (rms < high)), (rms.round(2), low, high)


def test_rate_integral_weights_give_the_change_of_the_pause_means():
    """Eq. 36 integrates the rate to the change of the pauses' mean angle: the weights of each
    phase add up to the time between the pauses' mean sample times (the acc's and mag's means
    weighted as their angles are), not to the window from the first row of the pause before
    to the last of the pause after (several seconds longer)."""
    seed = 3
    session = simulate_session(make_truth("random", stream_rng(seed, "truth")), seed)
    imu = {rec: session.si_frame(rec) for rec in session.logs}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        segments = segment_dataset(imu, ratetable=dict(_benchmark()._options(session).ratetable))
    truth = session.truth.calibration
    measuring = [("mag", truth.mag, MAG), ("acc", truth.acc, ACC)]
    table = imu["rotation3d"]
    angles = _phase_angles(table, segments, measuring)
    rows = segments[segments["recording"] == "rotation3d"].reset_index(drop=True)
    for label, phase in angles.items():
        i = int(np.flatnonzero(rows["label"] == label)[0])
        before, after = rows.iloc[i - 1], rows.iloc[i + 1]
        assert before["kind"] == after["kind"] == "static"
        t = table["t_s"].to_numpy()
        middle = np.mean(t[after.start_index : after.end_index])
        middle -= np.mean(t[before.start_index : before.end_index])
        window = phase["t_s"][-1] - phase["t_s"][0]
        # the mag's 10 Hz samples move each of its pause means by up to 0.05 s from the
        # rows' (its weight is ~1/40 in phases x and y, 1 in phase z)
        assert np.sum(phase["weights_s"]) == pytest.approx(middle, abs=0.11), label
        assert window - middle > 2.0, (label, window, middle)


def _run_full(mc, seed: int) -> list[dict]:
    """The benchmark's path ``full`` alone (its ``run_full`` runs the tool-free path too)."""
    session = simulate_session(make_truth("random", stream_rng(seed, "truth")), seed)
    imu = {rec: session.si_frame(rec) for rec in session.logs}
    fit = calibrate_session(imu, None, mc._options(session))
    return [
        mc._record(seed, "full", fit.calibration.sensor(s), session.truth.calibration.sensor(s))
        for s in ("acc", "gyr", "mag")
    ]


@pytest.mark.slow
@pytest.mark.parametrize(
    "protocol, sessions, groups",
    [
        (
            "full",
            8,
            {
                ("full", "acc"): ("bias", "scale", "xi_rad", "alpha_rad"),
                ("full", "gyr"): ("bias", "scale", "xi_rad", "alpha_rad"),
                ("full", "mag"): ("bias", "scale", "xi_rad", "alpha_rad"),
            },
        ),
        (
            "ferraris",
            6,
            {
                ("acc_known_orientation", "acc"): ("bias", "matrix"),
                ("gyr_known_rotation", "gyr"): ("bias", "matrix"),
            },
        ),
        (
            "poses",
            5,
            {("acc_cube", "acc"): ("bias", "matrix"), ("gyr_pose_to_pose", "gyr"): ("matrix",)},
        ),
        ("tumble", 8, {("mag_step1", "mag"): ("bias", "matrix")}),
    ],
)
def test_paths_report_the_std_of_their_errors(protocol, sessions, groups, rms_z_band):
    """The paper's chain (cube, rate table, ellipsoid, the alignments) and the partial paths
    (Ferraris' known orientations and known-angle turns, pose-to-pose gyroscope, the tumble's ellipsoid) over 5-8
    sessions each (a few seconds per session)."""
    mc = _benchmark()
    records = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in range(200, 200 + sessions):
            if protocol == "full":
                records += _run_full(mc, seed)
            else:
                records += mc.run_partial(seed, protocol, ())
    _check(_z(records), groups, rms_z_band)


def test_the_ferraris_path_ships_its_known_orientation_fit_within_its_std():
    """One session cut to the Ferraris protocol (six faces, known-angle turns): the partial
    path ships the known-orientation accelerometer and the known-rotation gyroscope (it raises
    when another stage's calibration is shipped), each (bias, matrix) error within its std
    times Student's t of the fit's 6 dof, two-sided over the 24 at 1e-4."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        records = _benchmark().run_partial(200, "ferraris", ())
    assert {r["path"] for r in records} == {"acc_known_orientation", "gyr_known_rotation"}
    for r in records:
        z = (np.subtract(r["estimate"], r["truth"]) / r["std"])[:12]
        assert np.all(np.abs(z) < z_limit(24, dof=6)), (r["path"], z.round(2))
