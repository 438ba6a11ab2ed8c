"""A session off the paper's protocol as a new user meets it: a module tumbled by hand with
pauses shorter than the default rest, declared from docs/data-format.md. With the defaults the
cube fit is refused with the setting and the value that would find the pauses; with that value
the README's own-data target builds the shipped calibration, checked on independent parts."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import partial_session

from imucal.constants import STANDARD_GRAVITY_M_S2
from imucal.io.dataset import read_dataset
from imucal.pipeline import partial
from imucal.segments.segmentation import segment_dataset
from imucal.sim import make_effect, make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.protocol import TumbleConfig
from imucal.sim.tumble import simulate_tumble

REPO = Path(__file__).resolve().parents[2]
#: The field the user's magnetometer reads, T (the session's field has norm 1).
FIELD_T = 50e-6
#: The refusal's hint: the setting and the value.
HINT = re.compile(
    r"segmentation\.min_static_s: ([0-9.]+) and segmentation\.window_s: ([0-9.]+) the "
    r"segmentation finds (\d+) rests in (\d+) distinct orientations"
)


def write_user_session(folder: Path, seed: int = 1) -> Path:
    """A hand-tumbled module (26 pauses of 0.5-0.9 s) as a logger writes it (s, g, deg/s, uT)
    and its dataset.yaml as docs/data-format.md declares such a recording."""
    truth = make_truth("mems", stream_rng(seed, "truth"))
    hand = (
        make_effect("hand_tremor", sway_mm=8.0),
        make_effect("lever_arm", x_m=0.1, y_m=0.05, z_m=0.03),
    )
    frame = simulate_tumble(truth, seed, TumbleConfig(move_s=(0.4, 0.8)), hand).si_frame()
    folder.mkdir(parents=True, exist_ok=True)
    log = {"time": frame["t_s"]}
    for axis in "xyz":
        log[f"a{axis}"] = frame[f"acc_{axis}"] / STANDARD_GRAVITY_M_S2
        log[f"g{axis}"] = np.degrees(frame[f"gyr_{axis}"])
        log[f"m{axis}"] = frame[f"mag_{axis}"] * FIELD_T * 1e6
    import pandas as pd

    pd.DataFrame(log).to_csv(folder / "tumble.csv", index=False, float_format="%.6f")
    declaration = {
        "name": "lab1",
        "description": "MEMS module turned by hand through 26 orientations, short pauses",
        "gravity_m_s2": 9.81,
        "field_norm_t": FIELD_T,
        "recordings": {
            "poses": {
                "reader": "table",
                "file": "tumble.csv",
                "columns": {
                    "t_s": "time",
                    **{f"acc_{a}": f"a{a}" for a in "xyz"},
                    **{f"gyr_{a}": f"g{a}" for a in "xyz"},
                    **{f"mag_{a}": f"m{a}" for a in "xyz"},
                },
                "units": {"acc": "g", "gyr": "deg/s", "mag": "uT"},
            }
        },
    }
    (folder / "dataset.yaml").write_text(yaml.safe_dump(declaration, sort_keys=False))
    return folder


def _acc_cube_reason(tables, **segmentation) -> str:
    segments = segment_dataset(tables, fallback=True, **segmentation)
    outcomes = partial.run_stages(partial_session(tables, segments))
    return next(o for o in outcomes if o.name == "acc_cube").reason, outcomes


def test_the_refusal_names_the_setting_and_the_value_that_find_the_pauses(tmp_path, ingest_imu):
    dataset = read_dataset(write_user_session(tmp_path / "lab1"))
    tables = ingest_imu(dataset)
    reason, _ = _acc_cube_reason(tables)
    assert "1 distinct orientation" in reason
    hint = HINT.search(reason)
    assert hint, reason
    min_static_s, window_s = float(hint.group(1)), float(hint.group(2))
    assert min_static_s < 1.0 and int(hint.group(4)) >= 9
    # with that value the rests are found and the cube fit runs
    again, outcomes = _acc_cube_reason(tables, min_static_s=min_static_s, window_s=window_s)
    assert next(o for o in outcomes if o.name == "acc_cube").status == "run", again


def _snakemake(work: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "snakemake", "--cores", "2", *args],
        cwd=work, env={**os.environ, "PYTHONPATH": str(REPO)},
        capture_output=True, text=True, timeout=1800, check=False,
    )  # fmt: skip


@pytest.mark.slow  # two runs of the workflow up to the calibration, about a minute each
def test_the_readme_target_ships_the_calibration_of_a_partial_session(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    for name in ("Snakefile", "config", "data", "workflow"):
        (work / name).symlink_to(REPO / name)
    folder = write_user_session(tmp_path / "lab1")
    (work / "my.yaml").write_text(f"datasets:\n  lab1: {folder}\n")
    # the README's command for one's own data, as written there
    run = _snakemake(work, "results/lab1/calibration.json", "--configfile", "my.yaml")
    assert run.returncode == 0, run.stdout + run.stderr
    calibration = json.loads((work / "results/lab1/calibration.json").read_text())
    hint = HINT.search(calibration["missing"]["acc"])
    assert hint, calibration["missing"]["acc"]
    # the value it names, in the user's config
    (work / "my.yaml").write_text(
        f"datasets:\n  lab1: {folder}\nsegmentation:\n  min_static_s: {hint.group(1)}\n"
        f"  window_s: {hint.group(2)}\n"
    )
    run = _snakemake(work, "results/lab1/calibration.json", "--configfile", "my.yaml")
    assert run.returncode == 0, run.stdout + run.stderr
    calibration = json.loads((work / "results/lab1/calibration.json").read_text())
    check = json.loads((work / "results/lab1/consistency.json").read_text())
    assert "acc" in calibration and check["sensors"]["acc"]["stage"] == "acc_cube"
    # the check's verdict is in the shipped calibration: inflated or warned
    acc = check["sensors"]["acc"]
    assert max(acc["inflation"].values()) > 1.0 or acc["warnings"]
    assert calibration["acc"]["warnings"] == acc["warnings"]
