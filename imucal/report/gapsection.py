"""The report's sim-to-real gap section and its sentence in the summary, from ``diagnosis.json``.

The verdict is written as a lab engineer would: how far the session departs from its twin,
which effects explain it with their sizes in physical units (:mod:`imucal.report.gapwords`)
and how much of the gap each closes on data withheld from its fit, what is left and whether it
is within noise. Effects are named in one order everywhere (the order the diagnosis added them
to the twin, :func:`imucal.report.gapfigures.ordered_effects`); statistic names appear only in
the details, beside their plain labels and units. A quantity the validation shows too (the
reference's clock offset) is reconciled with it and linked.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from imucal.report.artifacts import load_json
from imucal.report.figures import embed_figure
from imucal.report.gapfigures import ordered_effects
from imucal.report.gapwords import (
    effect_label,
    effect_size,
    location_phrase,
    location_place,
    number,
    statistic_label,
    statistic_unit,
)

#: Ordinals of the effects in the verdict.
_ORDINALS = ("first", "then", "then", "then", "then", "then")
#: Counts in words.
_COUNTS = {1: "One", 2: "Two", 3: "Three", 4: "Four", 5: "Five"}
#: A gap this many times what noise alone stays below is "far beyond" noise.
FAR_BEYOND = 10.0
#: Locations of the gap listed in the details.
LISTED_LOCATIONS = 20


def _with_size(e: Mapping) -> str:
    size = effect_size(e["name"], e.get("params"))
    return f"{effect_label(e['name'])} ({size})" if size else effect_label(e["name"])


def _kinds(diagnosis: Mapping) -> dict[str, str]:
    """Effect -> ``acquisition``, ``physical`` or ``reference`` (the diagnosis's verdict)."""
    verdict = diagnosis.get("verdict") if isinstance(diagnosis.get("verdict"), Mapping) else {}
    kinds = {e["name"]: e.get("kind", "physical") for e in verdict.get("effects", [])}
    kinds.update({g["effect"]: "reference" for g in verdict.get("lacks", []) if "effect" in g})
    return kinds


def _accepted(diagnosis: Mapping) -> list[Mapping]:
    return [e for e in ordered_effects(diagnosis) if e.get("accepted")]


def _departure(diagnosis: Mapping) -> str:
    gap, null = diagnosis["gap"], diagnosis.get("null") or {}
    n = null.get("n_locations") or len(diagnosis.get("all_locations", []))
    replicas = null.get("replicas")
    noise = (
        f"noise alone stays below {number(gap['null_p95'])} in 95 % of the twin's "
        f"{replicas} replicas"
        if replicas
        else f"noise alone stays below {number(gap['null_p95'])} in 95 % of the twin's replicas"
    )
    if not gap["significant"]:
        return (
            f"The session behaves like its simulated twin: none of its {n} statistics departs "
            f"from the twin beyond noise (gap {number(gap['total'])}; {noise})."
        )
    located = diagnosis.get("locations") or []
    top = f", most of all in the {location_phrase(located[0])}" if located else ""
    how = "far beyond" if gap["total"] > FAR_BEYOND * gap["null_p95"] else "beyond"
    return (
        f"The session departs from its simulated twin at {len(located)} of its {n} "
        f"statistics{top}: its gap, {number(gap['total'])}, is {how} what noise gives ({noise})."
    )


def _explanation(diagnosis: Mapping) -> str:
    accepted = _accepted(diagnosis)
    if not accepted:
        return ""
    kinds = _kinds(diagnosis)
    of = {k: [e for e in accepted if kinds.get(e["name"], "physical") == k]
          for k in ("acquisition", "physical", "reference")}  # fmt: skip
    if len(of["acquisition"]) == len(accepted):
        whose = " of the acquisition (clocks, radio link, logger) rather than of the sensor"
    elif len(of["reference"]) == len(accepted):
        whose = " of the reference rather than of the sensor"
    else:
        whose = ""
    count = _COUNTS.get(len(accepted), str(len(accepted)))
    explain = (
        "One effect outside the paper's model explains it"
        if len(accepted) == 1
        else (f"{count} effects outside the paper's model explain it")
    )
    if whose:
        explain += (
            f", {'both' if len(accepted) == 2 else 'all'}{whose}"
            if len(accepted) > 1
            else (f",{whose}")
        )
    parts = []
    for k, e in enumerate(accepted):
        held = e.get("heldout_shrink")
        if held is None:
            closes = "which closes the gap" if k == 0 else "which closes what was left"
        elif k == 0:
            closes = (
                f"which closes {number(100 * held, 3)} % of the gap on data its estimate did "
                "not use"
            )
        else:  # each effect is added to the twin after the ones before it
            closes = f"which closes {number(100 * held, 3)} % of what was left, also held out"
        beside = (
            " (judged on the statistics the twin replays)"
            if e.get("judged_beside_shortfalls")
            else ""
        )
        lead = _ORDINALS[min(k, len(_ORDINALS) - 1)] + " " if len(accepted) > 1 else ""
        parts.append(f"{lead}{_with_size(e)}, {closes}{beside}")
    return f"{explain}: " + "; ".join(parts) + "."


def _remaining(diagnosis: Mapping) -> str:
    gap, rem = diagnosis["gap"], diagnosis.get("remaining") or {}
    if not gap["significant"]:
        return ""
    verdict = diagnosis.get("verdict") if isinstance(diagnosis.get("verdict"), Mapping) else {}
    lacks = [g for g in verdict.get("lacks", []) if "effect" not in g]
    total = rem.get("total")
    left = f"What is left, a gap of {number(total)}," if total is not None else "What is left"
    if not rem.get("significant"):
        if not _accepted(diagnosis):
            return ""
        return f"{left} is within noise (below {number(gap['null_p95'])})."
    where = rem.get("locations") or []
    at = f", above all in the {location_phrase(where[0])}" if where else ""
    what = lacks[0]["what"] if lacks else "an effect the library does not hold"
    if not _accepted(diagnosis):
        return (
            f"No effect of the library closes the gap on data withheld from its fit: the twin "
            f"lacks {what}{at}."
        )
    return f"{left} is not within noise: the twin lacks {what}{at}."


def _noted(diagnosis: Mapping) -> str:
    noted = [n for n in diagnosis.get("noted", []) if n]
    if not noted:
        return ""
    parts = []
    for name in noted:
        params = {}
        if name == "large_misalignment":
            angles = (diagnosis.get("misalignment") or {}).get("angles_deg") or {}
            params = {f"{s}_deg": v for s, v in angles.items()}
        elif name == "saturation":
            parts.append(_saturation_noted(diagnosis))
            continue
        size = effect_size(name, params) if params else ""
        parts.append(f"{effect_label(name)}{f' ({size})' if size else ''}")
    return "Seen in the data but opening no gap: " + "; ".join(p for p in parts if p) + "."


def _saturation_noted(diagnosis: Mapping) -> str:
    fractions = (diagnosis.get("saturation") or {}).get("clip_fraction") or {}
    shares = ", ".join(f"{s} {number(100 * f, 2)} %" for s, f in fractions.items())
    return f"{effect_label('saturation')}" + (
        f" (readings at the range: {shares})" if shares else ""
    )


def reconcile_offset(
    diagnosis: Mapping | None, validation: Mapping | None, summary: Mapping | None
) -> dict | None:
    """The reference's clock offset as the validation and the gap diagnosis show it, reconciled.

    The validation's offset is the reference's clock at the module's first sample
    (``t_ref = offset + t_module``); less the reference's first time stamp (both on the
    reference's clock) it is how much earlier the reference started. The twin starts both
    recordings together, so that lead is what the diagnosis names a time offset.

    Returns
    -------
    dict or None
        ``validation_s``, ``first_stamp_s`` and ``lead_s`` (the reference's lead over the
        module, s) as text, with ``diagnosis_s`` (the diagnosis's estimate of the time offset)
        and ``accepted`` (whether the verdict names it), None without a diagnosis that
        estimated it; None when the validation or the summary lacks its part.
    """
    if not (validation and summary):
        return None
    offset = (validation.get("time_alignment") or {}).get("offset_s")
    recordings = summary.get("recordings") or {}
    first = (recordings.get("reference") or {}).get("t_start_s")
    module = (recordings.get("rotation3d") or {}).get("t_start_s") or 0.0
    if offset is None or first is None:
        return None
    effects = (diagnosis or {}).get("effects", [])
    effect = next((e for e in effects if e["name"] == "time_offset" and e.get("params")), None)
    estimate = None if effect is None else effect["params"].get("offset_s")
    return {
        "validation_s": number(offset, 6),
        "first_stamp_s": number(first, 6),
        "lead_s": number(float(offset) + float(module) - float(first)),
        "diagnosis_s": None if estimate is None else number(estimate),
        "accepted": bool(effect and effect.get("accepted")),
    }


def verdict_paragraph(diagnosis: Mapping) -> str:
    """The verdict in one paragraph of plain sentences (no statistic names)."""
    if diagnosis.get("scope") == "none":
        sentences = [
            "The session could not be compared with its simulated twin: "
            f"{diagnosis.get('reason', 'no statistic could be scored')}.",
            _noted(diagnosis),
        ]
    else:
        sentences = [_departure(diagnosis), _explanation(diagnosis), _remaining(diagnosis),
                     _noted(diagnosis)]  # fmt: skip
    return " ".join(s for s in sentences if s)


def verdict_sentence(diagnosis: Mapping | None) -> str | None:
    """The verdict in one sentence for the report's summary, with the effects' sizes."""
    if not diagnosis:
        return None
    if diagnosis.get("scope") == "none":
        return (
            "not compared with a simulated twin: "
            f"{diagnosis.get('reason', 'no statistic could be scored')}."
        )
    gap, rem = diagnosis.get("gap") or {}, diagnosis.get("remaining") or {}
    if not gap.get("significant"):
        return "nothing departs from the simulated twin beyond noise."
    accepted = _accepted(diagnosis)
    if not accepted:
        verdict = diagnosis.get("verdict") if isinstance(diagnosis.get("verdict"), Mapping) else {}
        lacks = [g for g in verdict.get("lacks", []) if "effect" not in g]
        what = lacks[0]["what"] if lacks else "an effect the library does not hold"
        return f"the session departs from its simulated twin and no effect explains it: the twin lacks {what}."
    names = [_with_size(e) for e in accepted]
    listed = names[0] if len(names) == 1 else ", then ".join(names)
    rest = (
        "what is left is not within noise"
        if rem.get("significant")
        else "what is left is within noise"
    )
    return f"explained by {listed}; {rest}."


def _effect_row(e: Mapping, rank: int | None) -> dict:
    def pct(x: Any) -> str:
        return "" if x is None else f"{number(100 * x, 3)} %"

    return {
        "label": effect_label(e["name"]),
        "name": e["name"],
        "accepted": f"yes ({rank})" if rank else "no",
        "size": effect_size(e["name"], e.get("params")) or "",
        "z": "" if e.get("detect_z") is None else number(e["detect_z"]),
        "shrink": pct(e.get("shrink")),
        "heldout": pct(e.get("heldout_shrink")),
        # the estimator's flags: what it refused to report as an estimate, and why
        "note": "; ".join(n for n in (e.get("note"), *(e.get("flags") or ())) if n),
    }


def _location_row(d: Mapping) -> dict:
    return {
        "label": statistic_label(d["statistic"]),
        "unit": statistic_unit(d["statistic"], d["sensor"]),
        "place": location_place(d),
        "z": number(d["z"]),
        "statistic": d["statistic"],
        "where": "/".join(str(d[k]) for k in ("stage", "sensor", "axis", "segment")),
    }


def gap_section(
    paths: Sequence[str | Path] | None,
    validation: Mapping | None = None,
    summary: Mapping | None = None,
) -> dict | None:
    """Context of the gap partial (``_gap.html.j2``): diagnosis.json, then its figures
    (``gap_map.png``, ``effects.png``), with the validation and the ingest summary for the
    reconciliation of the reference's clock offset."""
    if not paths:
        return None
    diagnosis, *figures = [Path(p) for p in paths]
    d = load_json(diagnosis, "gap diagnosis")
    context = {
        "scope": d.get("scope", "full"),
        "reason": d.get("reason", ""),
        "not_observable": d.get("not_observable", {}),
        "pose": d.get("pose"),
        "fallback": d.get("fallback"),
        "held_by_hand": d.get("held_by_hand", []),
        "static_source": d.get("static_source"),
        "paragraph": verdict_paragraph(d),
        "offset": reconcile_offset(d, validation, summary),
    }
    if context["scope"] == "none":
        return context
    accepted = [e["name"] for e in _accepted(d)]
    null = d.get("null") or {}
    return {
        **context,
        "gap": {k: number(v) for k, v in d["gap"].items() if k != "significant"},
        "significant": bool(d["gap"]["significant"]),
        "null": {
            "n_locations": null.get("n_locations"),
            "replicas": null.get("replicas"),
            "alpha": null.get("alpha"),
        },  # fmt: skip
        "effects": [
            _effect_row(e, accepted.index(e["name"]) + 1 if e["name"] in accepted else None)
            for e in ordered_effects(d)
        ],
        "locations": [_location_row(x) for x in (d.get("locations") or [])[:LISTED_LOCATIONS]],
        "n_locations_in_gap": len(d.get("locations") or []),
        "remaining": {
            "total": number((d.get("remaining") or {}).get("total", float("nan"))),
            "significant": bool((d.get("remaining") or {}).get("significant")),
        },
        "confusable": [
            {
                "accepted": effect_label(c["accepted"]),
                "rivals": [effect_label(r) for r in c.get("rivals", [])],
            }
            for c in d.get("confusable", [])
        ],  # fmt: skip
        "figures": {f.stem: embed_figure(f) for f in figures},
    }
