"""One options object: the config's fit settings reach every path through the chain.

The stage rules, the partial path and the in-process chain (the diagnosis's twin, the closed
loop) take their settings from :func:`imucal.pipeline.options.pipeline_settings`; a method set
in the config must change the shipped calibration whether or not a model term is in the model
(the closed loop refits the session in process).
"""

from __future__ import annotations

import json
import shutil
import subprocess
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from snakemake.utils import validate

from imucal.calibration import ImuCalibration
from imucal.columns import SENSORS
from imucal.gap.twin import TWIN_RECORDINGS, Twin, render_replica
from imucal.io import read_recording, read_segments
from imucal.io.dataset import read_dataset
from imucal.pipeline.full import calibrate_session
from imucal.pipeline.options import FitMethods, PipelineOptions, pipeline_settings
from imucal.sim import ProtocolConfig, make_effect, make_truth
from imucal.sim.effects import stream_rng
from imucal.sim.session import SENSITIVITY
from imucal.terms import TermSettings, close_loop

REPO = Path(__file__).resolve().parents[2]
SCHEMA = REPO / "workflow/schemas/config.schema.yaml"
SHORT = ProtocolConfig(static_s=120.0, run_plateau_s=3.0, run_pause_s=1.5)
RANGE = {"acc": 32767, "gyr": 32767, "mag": 32767}
RATETABLE = {"axes": list(SHORT.ratetable_axes), "rates_dps": list(SHORT.rates_dps)}
#: Every method away from its default.
OTHER = FitMethods(
    mag_refine_lm=False,
    mag_alignment="paper",
    acc_cube="samples",
    acc_alignment="paper",
    gyr_bias_estimator="mean",
    gyr_alignment="paper",
)
OTHER_CONFIG = {
    "magnetometer": {"refine_lm": False, "step2_method": "paper"},
    "accelerometer": {"cube_method": "samples", "alignment_method": "paper"},
    "gyroscope": {"bias_estimator": "mean", "alignment_method": "paper"},
}
G_ONLY = TermSettings.only(g_sensitivity="on")


def _validated(config: dict) -> dict:
    config = json.loads(json.dumps(config))
    validate(config, str(SCHEMA), set_default=True)
    return config


def test_defaults_are_the_schemas():
    settings = pipeline_settings(_validated({"datasets": {"x": "x"}}))
    assert settings["methods"] == asdict(FitMethods())
    defaults = PipelineOptions(9.81, {}, {}, None)
    assert settings["exact_rotation"] == defaults.exact_rotation
    assert settings["lowpass_order"] == defaults.lowpass_order
    assert settings["lowpass_cutoff_hz"] == defaults.lowpass_cutoff_hz


def test_config_sections_map_to_every_method():
    settings = pipeline_settings(_validated({"datasets": {"x": "x"}, **OTHER_CONFIG}))
    assert FitMethods.of(settings["methods"]) == OTHER


@pytest.fixture(scope="module")
def session():
    truth = make_truth("paper", stream_rng(0, "truth"))
    options = PipelineOptions(9.81, SENSITIVITY, RANGE, RATETABLE)
    twin = Twin(truth, SHORT, options, TWIN_RECORDINGS, True)
    imu, ref = render_replica(twin, 11, (make_effect("g_sensitivity"),))
    return imu, ref, options


def _difference(a: ImuCalibration, b: ImuCalibration, sensor: str) -> float:
    x, y = a.sensor(sensor), b.sensor(sensor)
    return float(max(np.max(np.abs(x.matrix - y.matrix)), np.max(np.abs(x.bias - y.bias))))


def test_methods_change_the_calibration_with_a_term_as_without(session):
    imu, ref, options = session
    chosen = {"default": options, "other": replace(options, methods=OTHER)}
    plain = {k: calibrate_session(imu, ref, o) for k, o in chosen.items()}
    looped = {
        k: close_loop(imu, ref, o, segments=plain[k].segments, diagnosis=None, settings=G_ONLY)
        for k, o in chosen.items()
    }
    assert all(r["calibration"] is not None for r in looped.values())
    for sensor in SENSORS:
        without = _difference(plain["default"].calibration, plain["other"].calibration, sensor)
        within = _difference(
            looped["default"]["calibration"], looped["other"]["calibration"], sensor
        )
        # the loop refits on the session with the term's effect taken out: the methods differ
        # there by about what they differ by on the session itself (the g-sensitivity the
        # term takes out moves the gyro's), never by nothing
        assert without > 0, sensor
        assert 0.25 * without < within < 4.0 * without, (sensor, without, within)
    for k, o in chosen.items():  # the shipped calibration is the refit with the chosen methods
        refit = calibrate_session(looped[k]["corrected"], ref, o, plain[k].segments)
        for sensor in SENSORS:
            assert _difference(refit.calibration, looped[k]["calibration"], sensor) < 1e-12


@pytest.mark.slow
def test_the_workflows_calibration_is_the_in_process_chains(tmp_path):
    """With every method away from its default and a term in the model, the stage rules and
    the closed loop ship what the in-process chain computes from the same settings."""
    work = tmp_path / "work"
    work.mkdir()
    for name in ("Snakefile", "workflow", "config"):
        src = REPO / name
        (shutil.copytree if src.is_dir() else shutil.copy)(src, work / name)
    subprocess.run(
        ["imucal", "simulate", str(work / "data/sim"), "--preset", "paper", "--seed", "5",
         "--static-s", "30", "--name", "sim", "--effect", "g_sensitivity"],
        check=True, capture_output=True,
    )  # fmt: skip
    config = {
        "datasets": {"sim": "data/sim"},
        **OTHER_CONFIG,
        "terms": {"temperature": "off", "g_sensitivity": "on", "mag_delay": "off",
                  "lever_arm": "off"},
    }  # fmt: skip
    (work / "config/config.yaml").write_text(yaml.safe_dump(config))
    targets = [f"results/sim/{name}.json" for name in ("acc", "gyr", "mag", "calibration")]
    run = subprocess.run(
        ["snakemake", *targets, "--cores", "2", "-q"], cwd=work, capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr[-3000:]

    results = work / "results/sim"
    names = [p.stem for p in (results / "ingest").glob("*.parquet")]
    imu = {n: read_recording(results / "ingest" / f"{n}.parquet")[0] for n in names}
    reference = imu.pop("reference", None)
    options = PipelineOptions.of_dataset(
        read_dataset(work / "data/sim"), **pipeline_settings(_validated(config))
    )
    assert options.methods == OTHER
    segments = read_segments(results / "segments.parquet")
    fit = calibrate_session(imu, reference, options, segments)
    for sensor in SENSORS:
        rule = json.loads((results / f"{sensor}.json").read_text())["calibration"]
        chain = fit.calibration.sensor(sensor)
        np.testing.assert_allclose(rule["matrix"], chain.matrix, rtol=0, atol=1e-10)
        np.testing.assert_allclose(rule["bias"], chain.bias, rtol=0, atol=1e-10)
    loop = close_loop(
        imu, reference, options, segments=segments, diagnosis=None,
        settings=TermSettings.from_config(config["terms"]),
    )  # fmt: skip
    shipped = ImuCalibration.from_dict(json.loads((results / "calibration.json").read_text()))
    assert shipped.terms.g_sensitivity is not None
    for sensor in SENSORS:
        assert _difference(shipped, loop["calibration"], sensor) < 1e-10, sensor
