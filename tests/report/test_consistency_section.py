"""The report's rows of the standard deviations checked on independent parts, and the Markdown
table of many sessions (docs/real-recordings.md shows the public recordings')."""

from __future__ import annotations

from imucal.report.consistency import COLUMNS, consistency_rows, markdown_table

CHECK = {
    "sensors": {
        "acc": {
            "stage": "acc_cube",
            "parts": {
                "scheme": "halves",
                "groups": {
                    "bias": {"rms_z": 1.01, "rank": 3},
                    "matrix": {"rms_z": 1.584, "rank": 6},
                    "scale": {"rms_z": 0.57, "rank": 3},
                    "xi_rad": {"rms_z": 0.9, "rank": 3},
                    "alpha_rad": {"rms_z": None, "rank": 0},
                    "all": {"rms_z": 5.34, "rank": 9},
                },
                "max_abs_z": 1.52,
                "max_parameter": "matrix_yz",
                "heldout": {"ratio": 1.76},
            },
            "leave_one_out": {"rms_z": 1.185, "n": 53, "basis": "poses"},
            "own_heldout": {"ratio": 0.0651},
            "inflation": {"bias": 3.45, "matrix": 5.46},
        },
        "gyr": {
            "stage": "gyr_known_rotation",
            "reason": "halves: part 1 shipped gyr_bias",
            "inflation": {"bias": 1.0, "matrix": 1.0},
        },
    }
}


def test_rows_give_each_group_with_its_rank_and_the_stage_own_heldout_first():
    acc, gyr = consistency_rows(CHECK)
    assert acc["matrix"] == "1.58 (6)" and acc["alpha_rad"] == "-" and acc["all"] == "5.34 (9)"
    assert acc["largest |z|"] == "1.5 (matrix_yz)"
    assert acc["left out one at a time"] == "1.19 (53)"
    assert acc["inflation (bias, matrix)"] == "x3.45, x5.46"
    assert acc["held out / nominal"] == "0.065"  # the stage's own, not the parts'
    assert gyr["scheme"] == "not split: halves: part 1 shipped gyr_bias"
    assert gyr["bias"] == "-" and gyr["held out / nominal"] == "-"


def test_the_markdown_table_has_a_row_per_dataset_and_sensor():
    table = markdown_table({"ck_explorer": CHECK, "other": CHECK}).splitlines()
    # a cell's "|" is escaped, so that the table keeps its columns
    assert table[0] == "| dataset | " + " | ".join(COLUMNS).replace("|z|", "\\|z\\|") + " |"
    assert all(line.replace("\\|", "").count("|") == len(COLUMNS) + 2 for line in table)
    assert len(table) == 2 + 4
    assert table[2].startswith("| `ck_explorer` | acc | acc_cube | halves | 1.01 (3) |")
