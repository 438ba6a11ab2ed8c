"""The terms of one calibration (:class:`ModelTerms`): name -> fitted term, in the registry's
order."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

from imucal.modelterms.contract import ModelTerm
from imucal.modelterms.registry import term_class, term_names


class ModelTerms(Mapping):
    """The optional terms of one calibration, name -> term, in the registry's order (any may
    be absent); read-only.

    ``ModelTerms(g_sensitivity=GSensitivity(...), ...)``: each keyword a registered term's
    name, its value an instance of that term's class, or None (absent). A term that holds
    nothing (a temperature term without polynomials) is absent too. A term is also an
    attribute, None when absent: ``terms.lever_arm``.

    Raises
    ------
    ValueError
        For a name no term is registered under, or a value of another class.
    """

    __slots__ = ("_terms",)

    def __init__(self, **terms: ModelTerm | None) -> None:
        unknown = sorted(set(terms) - set(term_names()))
        if unknown:
            raise ValueError(f"unknown model terms {unknown}; known: {list(term_names())}")
        for name, term in terms.items():
            cls = term_class(name)
            if term is not None and not isinstance(term, cls):
                raise ValueError(
                    f"model term {name!r} must be a {cls.__name__}, got {type(term).__name__}"
                )
        kept = {n: terms[n] for n in term_names() if terms.get(n) is not None and terms[n]}
        object.__setattr__(self, "_terms", kept)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("ModelTerms is read-only; build a new one")

    def __getattr__(self, name: str) -> ModelTerm | None:
        if name in term_names():
            return self._terms.get(name)
        raise AttributeError(f"ModelTerms has no attribute {name!r}")

    def __getitem__(self, name: str) -> ModelTerm:
        return self._terms[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._terms)

    def __len__(self) -> int:
        return len(self._terms)

    def __reduce__(self) -> tuple:
        return _from_terms, (dict(self._terms),)

    def __repr__(self) -> str:
        return f"ModelTerms({', '.join(f'{n}={t!r}' for n, t in self._terms.items())})"

    @property
    def empty(self) -> bool:
        return not self._terms

    def names(self) -> list[str]:
        """The terms present, in the order they are applied."""
        return list(self._terms)

    def to_dict(self) -> dict:
        return {name: term.to_dict() for name, term in self._terms.items()}

    @classmethod
    def from_dict(cls, d: Mapping) -> ModelTerms:
        unknown = sorted(set(d) - set(term_names()))
        if unknown:
            raise ValueError(
                f"calibration has unknown model terms {unknown}; known: {list(term_names())}"
            )
        return cls(**{name: term_class(name).from_dict(entry) for name, entry in d.items()})


def _from_terms(terms: dict) -> ModelTerms:
    """A :class:`ModelTerms` from name -> term (unpickling)."""
    return ModelTerms(**terms)
