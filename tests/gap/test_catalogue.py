"""The catalogue of effects: every effect of the simulator has, in every scope of the diagnosis,
an estimator or the reason that scope cannot observe it, and every model term answers an effect
the protocol's diagnosis estimates."""

from __future__ import annotations

import pytest

from imucal.gap import catalogue
from imucal.gap.static import NOT_OBSERVABLE
from imucal.modelterms import term_class, term_names
from imucal.sim.effects import EFFECTS


def test_every_effect_has_an_estimator_or_a_reason_in_every_scope():
    assert catalogue.contract_violations() == []
    entries = catalogue.catalogue()
    assert set(entries) == set(EFFECTS)
    for entry in entries.values():
        assert set(entry.estimated) | set(entry.not_observable) == set(catalogue.SCOPES)
        assert not set(entry.estimated) & set(entry.not_observable)
        assert all(entry.not_observable.values()), entry.name


def test_the_contract_names_an_effect_without_estimator_or_reason(monkeypatch):
    reasons = dict(NOT_OBSERVABLE)
    reasons.pop("lever_arm")
    reasons["no_such_effect"] = "a reason for nothing"
    monkeypatch.setattr("imucal.gap.static.NOT_OBSERVABLE", reasons)
    problems = catalogue.contract_violations()
    assert "static: 'lever_arm' has neither an estimator nor a reason" in problems
    assert "static: 'no_such_effect' is not an effect of the simulator" in problems


@pytest.mark.parametrize("term", term_names())
def test_every_model_term_answers_an_effect_the_protocol_estimates(term):
    effect = term_class(term).effect
    entry = catalogue.catalogue()[effect]
    assert entry.term == term and "protocol" in entry.estimated
