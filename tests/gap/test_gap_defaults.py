"""The Python defaults of the workflow's settings are the config schema's: one value each."""

import dataclasses
from pathlib import Path

import yaml

from imucal.gap import DiagnosisSettings
from imucal.pipeline.full import PipelineOptions

SCHEMA = Path(__file__).resolve().parents[2] / "workflow" / "schemas" / "config.schema.yaml"


def _schema() -> dict:
    return yaml.safe_load(SCHEMA.read_text())["properties"]


def _defaults(cls) -> dict:
    return {
        f.name: f.default for f in dataclasses.fields(cls) if f.default is not dataclasses.MISSING
    }


def test_diagnosis_settings_are_the_schema_section_gap() -> None:
    gap = _schema()["gap"]["properties"]
    defaults = _defaults(DiagnosisSettings)
    assert set(gap) == set(defaults)
    for name, spec in gap.items():
        value = defaults[name]
        assert (list(value) if isinstance(value, tuple) else value) == spec["default"], name


def test_pipeline_option_defaults_are_the_schema_defaults() -> None:
    schema = _schema()
    defaults = _defaults(PipelineOptions)
    assert defaults["exact_rotation"] == schema["exact_rotation"]["default"]
    assert defaults["lowpass_order"] == schema["lowpass"]["properties"]["order"]["default"]
    assert defaults["lowpass_cutoff_hz"] == schema["lowpass"]["properties"]["cutoff_hz"]["default"]
