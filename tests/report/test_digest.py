"""The report's headline and designed tables (imucal.report.digest)."""

import numpy as np

from imucal.report.digest import headline, stage_tables, validation_tables

VALIDATION = {
    "time_alignment": {"offset_s": 18.375, "offset_std_s": 4e-4, "drift_ppm": 10.3},
    "mounting": {"angle_deg": 2.497, "angle_std_deg": 0.0026},
    "metrics": {
        "raw": {"acc": {"n": 8072, "rms_norm_diff": 0.2133, "rms_angle_deg": 2.512}},
        "calibrated": {"acc": {"n": 8072, "rms_norm_diff": 0.02236, "rms_angle_deg": 0.1858}},
    },
}
CALIBRATION = {
    "acc": {"method": "step 1: cube fit (means); step 2: full (exact rotation)"},
    "gyr": {"method": "tool-free"},
    "missing": {"mag": "no stage of this sensor could run: mag_step1: needs rotation3d"},
}
ACC = {
    "step1": {
        "labels": [f"p{i:02d}" for i in range(12)],
        "n_samples": [756, 660, 810],
        "magnitude_error_before_m_s2": [0.3, -0.4, 0.5],
        "magnitude_error_after_m_s2": [3e-4, -4e-4, 5e-4],
        "chi2": 2.5154,
        "dof": 3,
    },
    "warnings": ["position p07 clipped"],
}


def test_headline_says_what_was_calibrated_how_well_and_on_what_basis():
    rows = headline(CALIBRATION, {"acc": ACC}, VALIDATION, [
        {"source": "acc.json", "text": "position p07 clipped"}])  # fmt: skip
    acc, gyr, mag = rows
    assert acc["what"].startswith("step 1: cube fit")
    assert acc["figures"] == ["magnitude error |v| − |v_ref| RMS 0.213 → 0.0224 m/s²",
                              "direction error RMS 2.51 → 0.186°"]  # fmt: skip
    assert acc["basis"].startswith("against the reference recording")
    assert acc["warnings"] == ["position p07 clipped"]
    assert gyr["figures"] == [] and gyr["basis"] == "no check of this sensor ran"
    assert (
        not mag["calibrated"] and mag["what"] == "not calibrated: no stage of this sensor could run"
    )


def test_without_a_reference_the_headline_falls_back_to_the_in_sample_figures():
    acc = headline(CALIBRATION, {"acc": ACC}, None, [])[0]
    rms_after = np.sqrt(np.mean(np.square([3e-4, -4e-4, 5e-4])))
    assert acc["figures"] == [f"|a| − g RMS at the cube positions 0.408 → {rms_after:.3g} m/s²"]
    assert "in-sample" in acc["basis"]


def test_stage_table_of_the_cube_fit_has_units():
    (table,) = stage_tables("acc", ACC)
    rows = {r["quantity"]: (r["cells"], r["unit"]) for r in table["rows"]}
    assert rows["positions"] == (["12"], "")
    assert rows["samples per position"] == (["660 to 810"], "")
    assert rows["|a| − g RMS over the positions, after"][1] == "m/s²"
    assert rows["χ² / degrees of freedom"] == (["2.52 / 3"], "")


def test_the_reference_clock_offset_is_explained():
    tables = validation_tables(VALIDATION)
    compare = tables[0]
    assert compare["kind"] == "compare" and compare["rows"][0]["calibrated"] == "0.02236"
    offset = tables[1]["rows"][0]
    assert offset["cells"] == ["18.375 ± 0.0004"] and offset["unit"] == "s"
    assert "started that far apart" in offset["note"]
