"""The `imucal apply` command: calibrate an ingested recording with a calibration.json."""

from __future__ import annotations

import numpy as np
import pandas as pd

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
    matrix = errormodel.compose([1.01, 0.99, 1.02], [0.01, 0.0, -0.01], [0.0, 0.02, 0.0])
    sensors = {
        s: SensorCalibration(s, [0.1, -0.1, 0.2], matrix, unit, {}, "test")
        for s, unit in (("acc", "m/s^2"), ("gyr", "rad/s"), ("mag", "normalised"))
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
    expected = errormodel.apply(matrix, [0.1, -0.1, 0.2], pd.DataFrame(table)[list(GYR)].to_numpy())
    np.testing.assert_allclose(out[list(GYR)].to_numpy(), expected, rtol=1e-12)
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
