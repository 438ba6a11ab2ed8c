"""Which optional terms enter the model: the config switch per term and the diagnosis's word.

A term is ``off`` (never), ``on`` (whenever its estimator can estimate it) or ``auto``
(when the gap diagnosis accepts the effect behind it with its held-out shrink); and which
calibration is the session's final one (:func:`final_calibration`).
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass

from imucal.modelterms.registry import (
    option_key,
    settings_schema,
    term_class,
    term_names,
)


@dataclass(frozen=True)
class TermSettings:
    """The config section ``terms``: a switch per registered term and the terms' options.

    Made with :meth:`from_config`, which validates the section against the schema of the
    registered terms (:func:`imucal.modelterms.registry.settings_schema`) and fills in its
    defaults; a term registered later than the settings were made is 'off' in them.

    Attributes
    ----------
    switches : dict of str to str
        Term -> 'off', 'on' or 'auto'.
    options : dict of str to dict
        Term -> its options (option -> value, in the term's units); the keyword arguments of
        its estimator.
    """

    switches: Mapping[str, str]
    options: Mapping[str, Mapping]

    @classmethod
    def from_config(cls, section: Mapping | None = None, **overrides) -> TermSettings:
        """The settings of a config's section ``terms`` (empty: every default), with
        ``overrides`` (config keys) on top.

        Raises
        ------
        ValueError
            Naming the key that is unknown (with the closest known one) or malformed, and what
            was expected.
        """
        import jsonschema

        schema = settings_schema()
        section = {**(section or {}), **overrides}
        known = schema["properties"]
        unknown = sorted(set(section) - set(known))
        if unknown:
            hints = []
            for key in unknown:
                close = difflib.get_close_matches(key, known, n=1)
                hints.append(f"{key!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
            raise ValueError(f"unknown terms settings {', '.join(hints)}; known: {sorted(known)}")
        values = {key: section.get(key, prop["default"]) for key, prop in known.items()}
        try:
            jsonschema.validate(values, schema)
        except jsonschema.ValidationError as err:
            where = ".".join(map(str, err.absolute_path))
            raise ValueError(f"terms.{where}: {err.message}") from None
        switches, options = {}, {}
        for name in term_names():
            switch = values[name]
            switches[name] = ("on" if switch else "off") if isinstance(switch, bool) else switch
            options[name] = {
                option: values[option_key(name, option)] for option in term_class(name).options
            }
        return cls(switches, options)

    @classmethod
    def only(cls, switch: str = "off", **switches: str) -> TermSettings:
        """Every term at ``switch`` but those named (term -> switch), options at their
        defaults."""
        return cls.from_config({name: switch for name in term_names()} | switches)

    def switch(self, term: str) -> str:
        """'off', 'on' or 'auto' ('off' for a term these settings do not hold)."""
        return self.switches.get(term, "off")

    def to_config(self) -> dict:
        """The section ``terms`` these settings are made of (every key, defaults filled in)."""
        out: dict = dict(self.switches)
        for name, opts in self.options.items():
            out.update({option_key(name, option): value for option, value in opts.items()})
        return out

    def wanted(self) -> list[str]:
        """Terms not switched off."""
        return [t for t in term_names() if self.switch(t) != "off"]

    @property
    def needs_diagnosis(self) -> bool:
        """Whether a term is 'auto' (decided on the session's diagnosis)."""
        return any(self.switch(t) == "auto" for t in term_names())


def decide(term: str, settings: TermSettings, diagnosis: Mapping | None) -> tuple[bool, str]:
    """Whether ``term`` is to be estimated, and why.

    Parameters
    ----------
    term : str
        A registered term's name (:func:`imucal.modelterms.term_names`).
    settings : TermSettings
    diagnosis : dict or None
        diagnosis.json of the session (needed for 'auto').

    Returns
    -------
    include : bool
    reason : str
    """
    switch = settings.switch(term)
    if switch == "off":
        return False, "off in the config"
    if switch == "on":
        return True, "on in the config"
    effect = term_class(term).effect
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
