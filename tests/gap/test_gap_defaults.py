"""The diagnosis functions' defaults are the config schema's: one value per setting."""

import inspect
from pathlib import Path

import pytest
import yaml

from imucal.gap.diagnosis import diagnose
from imucal.gap.static import diagnose_static

SCHEMA = Path(__file__).resolve().parents[2] / "workflow" / "schemas" / "config.schema.yaml"


@pytest.mark.parametrize("function", [diagnose, diagnose_static])
def test_diagnosis_defaults_are_the_schema_defaults(function) -> None:
    gap = yaml.safe_load(SCHEMA.read_text())["properties"]["gap"]["properties"]
    parameters = inspect.signature(function).parameters
    shared = [name for name in gap if name in parameters]
    assert {"replicas", "alpha", "seed", "min_heldout_shrink", "detect_z"} <= set(shared)
    for name in shared:
        default = parameters[name].default
        expected = gap[name]["default"]
        assert (list(default) if isinstance(default, tuple) else default) == expected, name
