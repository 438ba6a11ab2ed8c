"""The `imucal apply` command: calibrate an ingested recording with a calibration.json."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imucal import errormodel
from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.cli import main
from imucal.columns import ACC, GYR, MAG, TIME
from imucal.io import read_recording, write_calibration, write_recording


def test_apply_calibrates_and_refuses_a_second_time(tmp_path, capsys):
    rng = np.random.default_rng(0)
    n = 50
    table = {TIME: np.arange(n) / 100.0}
    for cols in (ACC, GYR, MAG):
        table.update({c: rng.normal(size=n) for c in cols})

    units = {
        **dict.fromkeys(ACC, "m/s^2"),
        **dict.fromkeys(GYR, "rad/s"),
        **dict.fromkeys(MAG, "normalised"),
    }
    write_recording(pd.DataFrame(table), tmp_path / "in.parquet", {"units": units, "source": "x"})
    # three different calibrations, so that one sensor's parameters applied to another fail
    truths = {
        "acc": (([1.01, 0.99, 1.02], [0.01, 0.0, -0.01], [0.0, 0.02, 0.0]), [0.1, -0.1, 0.2]),
        "gyr": (([0.95, 1.1, 1.05], [-0.02, 0.01, 0.0], [0.03, 0.0, -0.01]), [0.02, 0.03, -0.01]),
        "mag": (([1.2, 0.85, 1.0], [0.0, -0.03, 0.02], [-0.02, 0.01, 0.04]), [0.3, 0.2, -0.4]),
    }
    units = {"acc": "m/s^2", "gyr": "rad/s", "mag": "normalised"}
    matrices = {s: errormodel.compose(*parts) for s, (parts, _) in truths.items()}
    sensors = {
        s: SensorCalibration(s, truths[s][1], matrices[s], units[s], {}, "test") for s in truths
    }
    write_calibration(ImuCalibration(**sensors), tmp_path / "cal.json")

    assert (
        main(
            [
                "apply",
                str(tmp_path / "cal.json"),
                str(tmp_path / "in.parquet"),
                str(tmp_path / "out.parquet"),
            ]
        )
        == 0
    )
    out, meta = read_recording(tmp_path / "out.parquet")
    for s, cols in (("acc", ACC), ("gyr", GYR), ("mag", MAG)):
        raw = pd.DataFrame(table)[list(cols)].to_numpy()
        expected = errormodel.apply(matrices[s], truths[s][1], raw)
        np.testing.assert_allclose(out[list(cols)].to_numpy(), expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(out[TIME].to_numpy(), table[TIME])
    assert meta["calibrated"] is True

    # a calibrated recording is refused with a message, not a traceback, and nothing is written
    status = main(
        [
            "apply",
            str(tmp_path / "cal.json"),
            str(tmp_path / "out.parquet"),
            str(tmp_path / "twice.parquet"),
        ]
    )
    assert status == 2
    assert "already calibrated" in capsys.readouterr().err
    assert not (tmp_path / "twice.parquet").exists()


def test_apply_adds_the_parameter_std_columns(tmp_path):
    """--parameter-std: a bias-only covariance gives every sample the std of matrix @ d(bias)."""
    n = 20
    rng = np.random.default_rng(1)
    table = {TIME: np.arange(n) / 100.0}
    for cols in (ACC, GYR, MAG):
        table.update({c: rng.normal(size=n) for c in cols})
    units = {
        **dict.fromkeys(ACC, "m/s^2"),
        **dict.fromkeys(GYR, "rad/s"),
        **dict.fromkeys(MAG, "normalised"),
    }
    write_recording(pd.DataFrame(table), tmp_path / "in.parquet", {"units": units, "source": "x"})
    matrix = errormodel.compose([1.01, 0.99, 1.02], [0.01, 0.0, -0.01], [0.0, 0.02, 0.0])
    cov = np.zeros((21, 21))
    cov[:3, :3] = np.diag([1e-4, 4e-4, 9e-4])
    acc = SensorCalibration("acc", [0.1, -0.1, 0.2], matrix, "m/s^2", {}, "t", cov)
    others = {
        s: SensorCalibration(s, [0.0, 0.0, 0.0], np.eye(3), unit, {}, "t")
        for s, unit in (("gyr", "rad/s"), ("mag", "normalised"))
    }
    write_calibration(ImuCalibration(acc=acc, **others), tmp_path / "cal.json")
    args = [str(tmp_path / p) for p in ("cal.json", "in.parquet", "out.parquet")]
    assert main(["apply", *args, "--parameter-std"]) == 0
    out, _ = read_recording(tmp_path / "out.parquet")
    expected = np.sqrt(np.diag(matrix @ cov[:3, :3] @ matrix.T))
    for k, column in enumerate(ACC):
        np.testing.assert_allclose(out[column + "_param_std"], expected[k], rtol=1e-9)
    assert "gyr_x_param_std" not in out.columns  # no covariance, no column


def test_version_prints_the_package_version(capsys):
    import imucal

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out == f"imucal {imucal.__version__}\n"
