"""The fleet: sample sheet, parameters across units and over time, the calibration store."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from imucal.cli import main as imucal_main
from imucal.errormodel import compose
from imucal.fleet import (
    calibration_for,
    drift_table,
    flag_outliers,
    parameter_table,
    read_sample_sheet,
    store_index,
    summarize_fleet,
)
from imucal.fleet.summary import MIN_UNITS

HEADER = "dataset\tpath\tserial\tdate\toperator\n"


def _sheet(tmp_path, rows: list[str], header: str = HEADER) -> pd.DataFrame:
    path = tmp_path / "sessions.tsv"
    path.write_text("# fleet of the lab\n" + header + "".join(r + "\n" for r in rows))
    return path


def test_a_sample_sheet_is_read_with_absolute_paths_and_days(tmp_path) -> None:
    path = _sheet(tmp_path, ["a_1\tdata/a\tS1\t2026-03-01\tana", "a_2\t/abs/b\tS1\t2026-05-01\tbo"])
    sheet = read_sample_sheet(path)
    assert list(sheet["dataset"]) == ["a_1", "a_2"]
    assert sheet.loc[0, "path"] == str((tmp_path / "data" / "a").resolve())
    assert sheet.loc[1, "path"] == "/abs/b"
    assert sheet.loc[1, "date"] == pd.Timestamp("2026-05-01")


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        (
            ["a_1\tp\tS1\t2026-03-01\tana", "A-2\tp\tS1\t2026-03-02\tana"],
            r"line 4: column 'dataset'",
        ),
        (["a_1\tp\tS1\t01.03.2026\tana"], r"line 3: column 'date'"),
        (["a_1\tp\tS1\t2026-02-30\tana"], r"line 3: date '2026-02-30' is not a day"),
        (["a_1\tp\t\t2026-03-01\tana"], r"line 3: column 'serial'"),
        (["a_1\tp\tS1\t2026-03-01\tana", "a_1\tq\tS2\t2026-03-01\tbo"], r"\['a_1'\] repeat"),
    ],
)
def test_a_bad_row_is_refused_with_its_line(tmp_path, rows, message) -> None:
    with pytest.raises(ValueError, match=message):
        read_sample_sheet(_sheet(tmp_path, rows))


def test_a_sheet_without_a_column_is_refused(tmp_path) -> None:
    path = _sheet(tmp_path, ["a_1\tp\tS1\t2026-03-01"], header="dataset\tpath\tserial\tdate\n")
    with pytest.raises(ValueError, match=r"no column\(s\) \['operator'\]"):
        read_sample_sheet(path)


def _calibration(rng, acc_scale=(1.0, 1.0, 1.0), gyr_bias=None) -> dict:
    """A calibration JSON with parameters scattered like a batch of consumer parts."""
    out = {}
    for sensor, unit, bias_std in (
        ("acc", "m/s^2", 0.2),
        ("gyr", "rad/s", 0.01),
        ("mag", "1", 0.1),
    ):
        scale = np.asarray(acc_scale if sensor == "acc" else (1, 1, 1)) * rng.normal(1, 0.01, 3)
        xi, alpha = rng.normal(0, 0.005, 3), rng.normal(0, 0.01, 3)
        bias = rng.normal(0, bias_std, 3) if gyr_bias is None or sensor != "gyr" else gyr_bias
        out[sensor] = {
            "bias": list(bias), "matrix": compose(scale, xi, alpha).tolist(),
            "scale": list(scale), "xi_rad": list(xi), "alpha_rad": list(alpha),
            "unit_in": unit, "std": {"bias": [bias_std / 100] * 3},
        }  # fmt: skip
    return out


def _fleet(n_units: int, seed: int = 0):
    """``n_units`` units with one session each; unit U03's acc x scale is 20 % off."""
    rng = np.random.default_rng(seed)
    rows, cals = [], {}
    for k in range(1, n_units + 1):
        name = f"u{k:02d}"
        cals[name] = _calibration(rng, acc_scale=(0.8, 1, 1) if k == 3 else (1, 1, 1))
        rows.append((name, f"/d/{name}", f"U{k:02d}", pd.Timestamp("2026-01-01"), "x"))
    sheet = pd.DataFrame(rows, columns=["dataset", "path", "serial", "date", "operator"])
    return sheet, cals


def test_the_unit_with_a_damaged_axis_is_the_only_outlier() -> None:
    # 20 units, 36 parameter axes each: at 5 robust sigmas a Gaussian fleet flags 720 x 6e-7
    # values on average; the damaged axis sits ~20 sigmas out
    sheet, cals = _fleet(20)
    scores, note = flag_outliers(parameter_table(cals, sheet), z=5.0)
    assert note is None
    flagged = scores[scores["outlier"]]
    assert flagged[["serial", "sensor", "parameter", "axis"]].values.tolist() == [
        ["U03", "acc", "scale", "x"]
    ]
    assert flagged["z"].iloc[0] < -10


def test_too_few_units_are_not_scored_and_the_note_says_why() -> None:
    sheet, cals = _fleet(MIN_UNITS - 1)
    scores, note = flag_outliers(parameter_table(cals, sheet), z=5.0)
    assert scores.empty and f"at least {MIN_UNITS}" in note


def test_drift_between_sessions_is_scored_against_the_reported_std() -> None:
    rng = np.random.default_rng(1)
    bias = np.array([0.01, -0.02, 0.005])
    cals = {
        "s1": _calibration(rng, gyr_bias=bias),
        "s2": _calibration(rng, gyr_bias=bias + [0.01, 0, 0]),
    }
    sheet = pd.DataFrame(
        [
            ("s1", "/a", "U1", pd.Timestamp("2026-01-01"), "x"),
            ("s2", "/b", "U1", pd.Timestamp("2026-03-02"), "x"),
        ],
        columns=["dataset", "path", "serial", "date", "operator"],
    )
    drift = drift_table(parameter_table(cals, sheet))
    row = drift[
        (drift["sensor"] == "gyr") & (drift["parameter"] == "bias") & (drift["axis"] == "x")
    ]
    assert row["days"].item() == 60
    assert row["change"].item() == pytest.approx(0.01)
    assert row["per_day"].item() == pytest.approx(0.01 / 60)
    assert row["z"].item() == pytest.approx(0.01 / np.hypot(1e-4, 1e-4))
    # the scale has no reported std: no score
    assert drift[drift["parameter"] == "scale"]["z"].isna().all()


def _store() -> dict:
    sheet = pd.DataFrame(
        [
            ("b", "/b", "S1", pd.Timestamp("2026-05-01"), "x"),
            ("a", "/a", "S1", pd.Timestamp("2026-01-10"), "x"),
            ("c", "/c", "S2", pd.Timestamp("2026-02-01"), "x"),
        ],
        columns=["dataset", "path", "serial", "date", "operator"],
    )
    return store_index(sheet, {"a": "/r/a.json", "b": "/r/b.json", "c": "/r/c.json"})


@pytest.mark.parametrize(
    ("date", "dataset"),
    [("2026-01-10", "a"), ("2026-04-30", "a"), ("2026-05-01", "b"), ("2027-01-01", "b")],
)
def test_the_store_returns_the_calibration_valid_at_a_date(date, dataset) -> None:
    assert calibration_for(_store(), "S1", date)["dataset"] == dataset


def test_the_store_refuses_dates_before_the_first_calibration_and_unknown_units() -> None:
    with pytest.raises(
        ValueError, match="no calibration on or before 2026-01-09; its first is 2026-01-10"
    ):
        calibration_for(_store(), "S1", "2026-01-09")
    with pytest.raises(ValueError, match="serial 'S9' is not in the store"):
        calibration_for(_store(), "S9", "2026-06-01")


def test_imucal_lookup_prints_the_calibration_path(tmp_path, capsys) -> None:
    store = tmp_path / "store.json"
    store.write_text(json.dumps(_store()))
    assert imucal_main(["lookup", str(store), "S2", "2026-03-01"]) == 0
    assert capsys.readouterr().out.strip() == "/r/c.json"
    assert imucal_main(["lookup", str(store), "S2", "2026-01-01"]) == 2
    # without a store: say that the fleet target writes it from a sample sheet
    capsys.readouterr()
    assert imucal_main(["lookup", str(tmp_path / "none.json"), "S2", "2026-03-01"]) == 2
    err = capsys.readouterr().err
    assert "no calibration store here" in err and "sample sheet" in err
    assert "config fleet.sessions" in err


def test_the_summary_lists_the_outlier_unit_and_the_store() -> None:
    sheet, cals = _fleet(12)
    summary, table, _ = summarize_fleet(
        sheet, cals, {d: f"/r/{d}.json" for d in cals}, outlier_z=5.0, drift_z=3.0
    )
    assert summary["outlier_units"] == ["U03"] and summary["n_units"] == 12
    assert summary["store_index"]["U03"][0]["calibration"] == "/r/u03.json"
    assert len(table) == 12 * 3 * 4 * 3


def test_fleets_without_a_bad_unit_are_almost_never_flagged() -> None:
    # 100 fleets of 12 ordinary units, 36 parameter axes each: 43,200 values tested at the
    # two-sided probability of 5 sigmas (5.7e-7), 0.025 false flags expected; more than 2 would
    # happen with probability < 3e-6 if the test held its level
    rng = np.random.default_rng(7)
    flags = 0
    for _ in range(100):
        cals = {f"u{k:02d}": _calibration(rng) for k in range(12)}
        sheet = pd.DataFrame(
            [(d, "/", d.upper(), pd.Timestamp("2026-01-01"), "x") for d in cals],
            columns=["dataset", "path", "serial", "date", "operator"],
        )
        scores, _ = flag_outliers(parameter_table(cals, sheet), z=5.0)
        flags += int(scores["outlier"].sum())
    assert flags <= 2
