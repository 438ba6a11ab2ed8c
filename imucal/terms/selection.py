"""Which optional terms enter the model: the config switch per term and the diagnosis's word.

A term is ``off`` (never), ``on`` (whenever its estimator can estimate it) or ``auto``
(when the gap diagnosis accepts the effect behind it with its held-out shrink); and which
calibration is the session's final one (:func:`final_calibration`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

from imucal.gap.catalogue import EFFECT_OF_TERM
from imucal.terms.modelterms import TERMS

SWITCHES = ("off", "on", "auto")


@dataclass(frozen=True)
class TermSettings:
    """The config section ``terms`` (defaults are the schema's).

    Attributes
    ----------
    temperature, g_sensitivity, mag_delay, lever_arm : str
        'off', 'on' or 'auto' (YAML's unquoted off/on arrive as False/True and are read so).
    temperature_max_order : int
        Highest order of a bias polynomial tried (>= 1).
    temperature_min_span_c : float
        Smallest temperature span (K) of the resting segments for a polynomial.
    temperature_margin_c : float
        How far outside the calibrated span (K) ``apply`` still calibrates (flagged).
    """

    temperature: str = "auto"
    g_sensitivity: str = "auto"
    mag_delay: str = "auto"
    lever_arm: str = "auto"
    temperature_max_order: int = 3
    temperature_min_span_c: float = 2.0
    temperature_margin_c: float = 1.0

    def __post_init__(self) -> None:
        for term in TERMS:
            value = getattr(self, term)
            if isinstance(value, bool):
                value = "on" if value else "off"
                object.__setattr__(self, term, value)
            if value not in SWITCHES:
                raise ValueError(f"terms.{term} is {value!r}; expected one of {SWITCHES}")
        if self.temperature_max_order < 1:
            raise ValueError(
                f"terms.temperature_max_order must be >= 1, got {self.temperature_max_order}"
            )

    @classmethod
    def from_config(cls, section: Mapping) -> TermSettings:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(section) - known)
        if unknown:
            raise ValueError(f"unknown terms settings {unknown}; known: {sorted(known)}")
        return cls(**section)

    def wanted(self) -> list[str]:
        """Terms not switched off."""
        return [t for t in TERMS if getattr(self, t) != "off"]

    @property
    def needs_diagnosis(self) -> bool:
        """Whether a term is 'auto' (decided on the session's diagnosis)."""
        return any(getattr(self, t) == "auto" for t in TERMS)


def decide(term: str, settings: TermSettings, diagnosis: Mapping | None) -> tuple[bool, str]:
    """Whether ``term`` is to be estimated, and why.

    Parameters
    ----------
    term : str
        One of :data:`imucal.terms.modelterms.TERMS`.
    settings : TermSettings
    diagnosis : dict or None
        diagnosis.json of the session (needed for 'auto').

    Returns
    -------
    include : bool
    reason : str
    """
    switch = getattr(settings, term)
    if switch == "off":
        return False, "off in the config"
    if switch == "on":
        return True, "on in the config"
    effect = EFFECT_OF_TERM[term]
    records = {e["name"]: e for e in (diagnosis or {}).get("effects", [])}
    if effect not in records:
        return False, f"auto: the diagnosis did not estimate {effect} on this session"
    e = records[effect]
    shrink = e.get("heldout_shrink")
    least = (diagnosis.get("settings") or {}).get("min_heldout_shrink")
    told = f"held-out shrink {shrink:.2f}" if shrink is not None else "no held-out shrink"
    bound = f" (at least {least:g} needed)" if least is not None else ""
    if e.get("accepted"):
        return True, f"auto: the diagnosis accepts {effect}, {told}{bound}"
    note = f"; {e['note']}" if e.get("note") else ""
    return False, f"auto: the diagnosis does not accept {effect}, {told}{bound}{note}"


def final_calibration(paper: Mapping, summary: Mapping) -> dict:
    """calibration.json: the closed loop's recalibration when it has terms, else the paper's
    calibration unchanged (byte for byte what the loop switched off writes)."""
    return dict(summary["calibration"]) if summary.get("calibration") else dict(paper)
