"""A misspelt terms setting is refused with the closest known one."""

from __future__ import annotations

import pytest

from imucal.terms.selection import TermSettings


def test_an_unknown_setting_names_the_closest_known_one():
    with pytest.raises(ValueError, match=r"'temprature' \(did you mean 'temperature'\?\)"):
        TermSettings.from_config({"temprature": "auto"})
    with pytest.raises(ValueError, match=r"'zzz'; known"):
        TermSettings.from_config({"zzz": 1})
