"""What the diagnosis's simulated checks show together: spread effects named where they were not
injected, over every session of the blind, stress and outside-library sets.

A spread effect of the library (the spec's kind ``spread``: a wandering bias, a jitter, a
placement error) widens the twin's null, so it is the one a flexible diagnosis names for a
departure it cannot explain. Its false names are counted over all sets at once
(:func:`spread_false_names`), from the sets' diagnoses and their sealed answer keys; the
README's and docs/gap.md's sentences are rendered from the same counts (:func:`check_sentences`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

from imucal.gap.library.registry import registered_specs


def spread_effects() -> tuple[str, ...]:
    """The library's effects of kind ``spread``."""
    return tuple(s.name for s in registered_specs() if s.kind == "spread")


def injected_effects(spec: Mapping) -> set[str]:
    """Every effect a session's spec rendered (library or outside), by name."""
    names = {e["effect"] for e in spec.get("effects", [])}
    names |= set(spec.get("diagnosable", []))
    if spec.get("effect"):
        names.add(spec["effect"])
    return names


def spread_false_names(
    diagnoses: Mapping[str, Mapping[str, Mapping]], keys: Mapping[str, Mapping[str, Mapping]]
) -> dict:
    """Sessions where a spread effect was explained without being injected.

    Parameters
    ----------
    diagnoses, keys : dict
        Check name (``blind``, ``stress``, ``outside``) -> session -> its diagnosis, and its
        sealed answer key (with ``spec``). A session without a key is not counted.

    Returns
    -------
    dict
        ``effects`` (the spread effects), ``by_check`` (check -> [k, n]), ``total`` ([k, n])
        and ``sessions`` (check/session -> the spread effects wrongly named).
    """
    spread = set(spread_effects())
    by_check, wrong = {}, {}
    for check in sorted(keys):
        k = 0
        for name, key in sorted(keys[check].items()):
            named = set(diagnoses[check][name].get("explained") or []) & spread
            false = sorted(named - injected_effects(key["spec"]))
            if false:
                k += 1
                wrong[f"{check}/{name}"] = false
        by_check[check] = [k, len(keys[check])]
    total = [sum(v[0] for v in by_check.values()), sum(v[1] for v in by_check.values())]
    return {"effects": sorted(spread), "by_check": by_check, "total": total, "sessions": wrong}


#: Beyond this |z| a location's score is taken to come from a null without spread (a statistic
#: its replicas give alike), which the diagnosis must leave unscored instead.
Z_WITHOUT_SPREAD = 1e3


def largest_z(diagnoses: Mapping[str, Mapping[str, Mapping]]) -> dict:
    """The largest |z| of any location of any session, per check, and the sessions beyond
    :data:`Z_WITHOUT_SPREAD`.

    Parameters
    ----------
    diagnoses : dict
        Check -> session -> its diagnosis (its ``all_locations``, each with ``z``).

    Returns
    -------
    dict
        ``by_check`` (check -> the largest finite |z|, None without a scored location) and
        ``beyond`` (check/session names with a |z| above :data:`Z_WITHOUT_SPREAD`).
    """
    by_check, beyond = {}, []
    for check in sorted(diagnoses):
        top = None
        for name, diag in sorted(diagnoses[check].items()):
            z = [
                abs(loc["z"]) for loc in diag.get("all_locations") or [] if loc.get("z") is not None
            ]
            z = [v for v in z if v == v]
            if not z:
                continue
            top = max(z) if top is None else max(top, max(z))
            if max(z) > Z_WITHOUT_SPREAD:
                beyond.append(f"{check}/{name}")
        by_check[check] = top
    return {"by_check": by_check, "beyond": beyond}


def _of(kn) -> str:
    return f"{kn[0]} of {kn[1]}"


def check_sentences(
    scores: Mapping[str, Mapping], spread: Mapping, z: Mapping | None = None
) -> str:
    """The checks' results in sentences, every figure from a score.

    Parameters
    ----------
    scores : dict
        Check -> its score (:func:`imucal.gap.blind.score_blind`,
        :func:`imucal.gap.stress.score_stress`, :func:`imucal.gap.outside.score_outside`);
        a check that has not run is left out.
    spread : dict
        :func:`spread_false_names` over the same sessions.
    z : dict, optional
        :func:`largest_z` over the same sessions.
    """
    text = []
    if "blind" in scores:
        b = scores["blind"]
        text.append(
            f"Blind set ({b['n']} sessions): {_of(b['fully_right'])} fully right, "
            f"{b['crashes']} crashes, nothing explained in {_of(b['null_explained_empty'])} "
            "sessions without an effect."
        )
    if "stress" in scores:
        s = scores["stress"]
        text.append(
            f"Stress set ({s['n']} sessions): {_of(s['fully_right'])} fully right, "
            f"{s['crashes']} crashes, nothing explained in {_of(s['null_explained_empty'])} "
            "sessions without a library effect."
        )
    if "outside" in scores:
        o = scores["outside"]
        text.append(
            f"Outside-library set ({o['right'][1]} sessions): {_of(o['right'])} fully right; "
            f"no library effect named for the outside one in {_of(o['no_library_name'])}, the "
            f"library effect beside it named in {_of(o['partner_named'])}, the verdict saying "
            f"what the twin lacks, at a location, in {_of(o['lacks_stated'])}; "
            f"{o['crashes']} crashes."
        )
    text.append(
        f"A spread effect ({', '.join(spread['effects'])}) named where it was not injected: "
        f"{_of(spread['total'])} sessions of these sets"
        + (f" ({', '.join(sorted(spread['sessions']))})." if spread["sessions"] else ".")
    )
    if z is not None:
        tops = [f"{c} {v:.3g}" for c, v in z["by_check"].items() if v is not None]
        text.append(
            f"The largest |z| of any location: {', '.join(tops)}; above {Z_WITHOUT_SPREAD:g} in "
            f"{len(z['beyond'])} sessions ({', '.join(z['beyond']) or 'none'}: a departure far "
            "beyond noise, or a null without spread, which the diagnosis should leave unscored; "
            "this count does not tell them apart)."
        )
    return " ".join(text)


def summarize_checks(files: Mapping[str, Mapping[str, Sequence]]) -> tuple[dict, str]:
    """The checks' summary from their files.

    Parameters
    ----------
    files : dict
        Check -> ``diagnoses`` (paths of the sessions' diagnosis JSON, named by session),
        ``sealed`` (their answer keys, same names) and ``score`` (the check's score JSON).

    Returns
    -------
    summary : dict
        ``scores`` (check -> its score without the per-session detail), ``spread_false``
        (:func:`spread_false_names`) and ``largest_z`` (:func:`largest_z`).
    text : str
        :func:`check_sentences` of it.
    """
    diagnoses, keys, scores = {}, {}, {}
    for check, f in files.items():
        diagnoses[check] = {Path(p).stem: json.loads(Path(p).read_text()) for p in f["diagnoses"]}
        keys[check] = {Path(p).stem: json.loads(Path(p).read_text()) for p in f["sealed"]}
        score = json.loads(Path(f["score"]).read_text())
        scores[check] = {k: v for k, v in score.items() if k not in ("sessions", "unknown")}
    spread, z = spread_false_names(diagnoses, keys), largest_z(diagnoses)
    summary = {"scores": scores, "spread_false": spread, "largest_z": z}
    return summary, check_sentences(scores, spread, z)
