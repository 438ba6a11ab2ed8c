"""The outside-library check: sessions with physics the diagnosis's library does not hold.

Each effect outside the library (:mod:`imucal.sim.outside`) is rendered at two magnitudes (its
realistic size and :data:`HARSH` times it), alone and beside one library effect at its realistic
size (:data:`PARTNERS`, a different one per magnitude), on the blind check's protocol; the
answer keys are sealed as the blind check's (:func:`imucal.gap.blind.render_blind_session`).
Right, for a session with an outside effect, is what a lab engineer can act on
(:func:`outside_verdict`): no library effect named for it, the library effect beside it named,
and the verdict saying that the twin lacks an effect the library does not hold, with the
locations where the gap lies. Clean sessions must name nothing.
"""

from __future__ import annotations

from collections.abc import Mapping

from imucal.sim.effects import stream_rng
from imucal.sim.outside import OUTSIDE

#: The larger of the two magnitudes, a factor on the realistic size.
HARSH = 3.0

#: Outside effect -> the library effects rendered beside it, one per magnitude (realistic,
#: harsh): each library effect with a signature of its own, none the outside effect's twin.
PARTNERS = {
    "rate_sign_scale": ("lever_arm", "temperature_drift"),
    "acc_sign_scale": ("time_offset", "g_sensitivity"),
    "bias_step": ("packet_loss", "mag_latency"),
    "g2_sensitivity": ("temperature_drift", "platform_magnetic"),
    "acc_cross_product": ("mag_latency", "scale_nonlinearity"),
    "output_filter": ("placement_error", "lever_arm"),
}


def outside_plan(seed: int, n_clean: int = 2) -> list[dict]:
    """The outside-library check's sessions, deterministic from ``seed``.

    Parameters
    ----------
    seed : int
    n_clean : int
        Sessions without any effect.

    Returns
    -------
    list of dict
        In name order (``o00``, ``o01``, ..., shuffled by the seed): ``name``, ``seed``,
        ``effects`` (simulator effects with parameters), ``outside`` (the outside effect or
        None), ``factor`` (its magnitude's factor), ``diagnosable`` (the library effects
        injected), ``exclude`` (empty), ``description``.
    """
    unknown = sorted(set(PARTNERS) ^ set(OUTSIDE))
    if unknown:
        raise ValueError(f"outside effects without partners, or partners of none: {unknown}")
    specs = [{"outside": None, "factor": None, "effects": [], "diagnosable": []}] * n_clean
    for name, partners in PARTNERS.items():
        for factor, partner in zip((1.0, HARSH), partners, strict=True):
            params = OUTSIDE[name]().scaled(factor).params()
            outside = {"effect": name, "params": params}
            specs.append({"outside": name, "factor": factor, "effects": [outside],
                          "diagnosable": []})  # fmt: skip
            specs.append({"outside": name, "factor": factor,
                          "effects": [outside, {"effect": partner, "params": {}}],
                          "diagnosable": [partner]})  # fmt: skip
    order = stream_rng(seed, "outside/plan").permutation(len(specs))
    return [
        {
            "name": f"o{i:02d}",
            "seed": int(seed * 1000 + i),
            **specs[j],
            "exclude": [],
            "effect": specs[j]["outside"],
            "description": "outside-library check session (answer key sealed)",
        }  # fmt: skip
        for i, j in enumerate(order)
    ]


def outside_verdict(diagnosis: Mapping, spec: Mapping) -> dict:
    """How a diagnosis answers one session of the check.

    Returns
    -------
    dict
        ``library_named`` (explained library effects that were not injected), ``partner_named``
        (every injected library effect explained, or noted where the check counts a note),
        ``lacks`` (the verdict says the twin lacks an effect the library does not hold, with a
        location), ``right`` (all three as they should be: nothing else named, the partner
        named, and for an outside effect the twin's lack stated).
    """
    explained = list(diagnosis.get("explained") or [])
    injected = set(spec.get("diagnosable", []))
    extra = [e for e in explained if e not in injected]
    partner = injected <= set(explained)
    verdict = diagnosis.get("verdict") or {}
    lacks = any(
        item.get("what") == "an effect the library does not hold" and item.get("top")
        for item in verdict.get("lacks", [])
    )
    says_lacks = lacks or (verdict.get("outcome") == "twin lacks" and bool(verdict.get("lacks")))
    right = not extra and partner and (spec.get("outside") is None or says_lacks)
    if spec.get("outside") is None:
        right = right and not explained
    return {"library_named": extra, "partner_named": partner, "lacks": says_lacks, "right": right}


def score_outside(diagnoses: Mapping[str, Mapping], keys: Mapping[str, Mapping]) -> dict:
    """Unsealed scoring of the outside-library check.

    Returns
    -------
    dict
        ``right`` (k, n) over every session; ``no_library_name`` (k, n) over the sessions with
        an outside effect: no library effect named that was not injected; ``partner_named``
        (k, n) over the sessions with a partner; ``lacks_stated`` (k, n) over the sessions with
        an outside effect: the verdict says the twin lacks an effect the library does not hold,
        at a location; ``clean_silent`` (k, n); ``crashes``; ``by_effect`` (outside effect ->
        right k, n); ``spread_named`` (sessions where a spread effect of the library was named
        without being injected); ``sessions`` (the detail).
    """
    rows = []
    for name in sorted(keys):
        spec, diag = keys[name]["spec"], diagnoses[name]
        v = outside_verdict(diag, spec)
        rows.append({
            "name": name, "outside": spec.get("outside"), "factor": spec.get("factor"),
            "partners": list(spec.get("diagnosable", [])),
            "explained": list(diag.get("explained") or []), "failed": diag.get("failed"),
            "sentence": (diag.get("verdict") or {}).get("sentence", ""), **v,
        })  # fmt: skip

    def tally(selected: list[dict], key: str) -> list[int]:
        return [sum(bool(r[key]) for r in selected), len(selected)]

    outside = [r for r in rows if r["outside"]]
    with_partner = [r for r in rows if r["partners"]]
    for r in outside:
        r["no_library_name"] = not r["library_named"]
    by_effect: dict = {}
    for r in outside:
        by_effect.setdefault(r["outside"], []).append(r)
    return {
        "right": tally(rows, "right"),
        "no_library_name": tally(outside, "no_library_name"),
        "partner_named": tally(with_partner, "partner_named"),
        "lacks_stated": tally(outside, "lacks"),
        "clean_silent": tally([r for r in rows if not r["outside"]], "right"),
        "crashes": sum(bool(r["failed"]) for r in rows),
        "by_effect": {k: tally(v, "right") for k, v in sorted(by_effect.items())},
        "sessions": rows,
    }


def _factor(factor: float | None) -> str:
    return "" if factor in (None, 1.0) else f" x{factor:g}"


def render_outside_page(score: Mapping) -> str:
    """The outside-library check's report page (self-contained HTML)."""
    from html import escape

    def frac(k_n) -> str:
        return f"{k_n[0]} of {k_n[1]}"

    by = "".join(
        f"<tr><th>{escape(k)}</th><td>{frac(v)}</td></tr>" for k, v in score["by_effect"].items()
    )
    rows = "".join(
        f"<tr><td>{escape(r['name'])}</td><td>{escape(r['outside'] or 'clean')}"
        f"{_factor(r['factor'])}</td>"
        f"<td>{escape(', '.join(r['partners']))}</td><td>{escape(', '.join(r['explained']))}</td>"
        f"<td>{'yes' if r['right'] else ''}</td><td>{escape(r['sentence'])}</td></tr>"
        for r in score["sessions"]
    )
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>Outside-library check</title>
<style>body{{font-family:sans-serif;max-width:72em;margin:auto}}td,th{{border:1px solid #ccc;
padding:2px 6px}}table{{border-collapse:collapse}}</style></head><body>
<h1>Outside-library check of the gap diagnosis</h1>
<p>Sessions with effects the library does not hold (docs/gap.md). Right: <b>{frac(score["right"])}</b>.
No library effect named for an outside one: <b>{frac(score["no_library_name"])}</b>; the library
effect beside it named: <b>{frac(score["partner_named"])}</b>; the verdict says what the twin
lacks, with its location: <b>{frac(score["lacks_stated"])}</b>; clean sessions silent:
<b>{frac(score["clean_silent"])}</b>; crashes: <b>{score["crashes"]}</b>.</p>
<h2>By outside effect</h2><table><tr><th>effect</th><th>right</th></tr>{by}</table>
<h2>Sessions</h2><table><tr><th>session</th><th>outside effect</th><th>beside</th>
<th>explained</th><th>right</th><th>verdict</th></tr>{rows}</table>
</body></html>
"""
