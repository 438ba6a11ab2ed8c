"""The pages of the diagnosis's checks (blind check, detection sweep), self-contained HTML.

The lab report's gap section and its figures are drawn from ``diagnosis.json`` in the report
layer (:mod:`imucal.report.gapsection`, :mod:`imucal.report.gapfigures`).
"""

from __future__ import annotations

from collections.abc import Mapping
from html import escape


def _percent(x) -> str:
    """A share as a percentage, or 'n/a' when it is undefined (no gap to close)."""
    return "n/a" if x is None else f"{x:.0%}"


def _page(title: str, body: str) -> str:
    """A self-contained HTML page of a check of the diagnosis (blind check, detection sweep)."""
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>{escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:auto}}td,th{{border:1px solid #ccc;
padding:2px 6px;text-align:center}}table{{border-collapse:collapse}}</style></head><body>
{body}
</body></html>
"""


def render_blind_page(score: Mapping, detection: Mapping | None = None) -> str:
    """The blind check's report page (self-contained HTML).

    Parameters
    ----------
    score : mapping
        :func:`imucal.gap.blind.score_blind`'s score.
    detection : mapping, optional
        A detection sweep's score (:func:`imucal.gap.detection.score_detection`): its
        detection limits and clean sessions' false positives are shown beside the blind check;
        without one the page says that no sweep was run.
    """
    effects = sorted(score["confusion"])
    named = sorted({n for row in score["confusion"].values() for n in row})
    head = "".join(f"<th>{escape(n)}</th>" for n in named)
    body = "".join(
        f"<tr><th>{escape(t)}</th>"
        + "".join(f"<td>{score['confusion'][t].get(n, '')}</td>" for n in named)
        + "</tr>"
        for t in effects
    )
    unknown = "".join(
        f"<li>{escape(u['name'])}: {escape(u['effect'])} left out of the library; flagged "
        f"unexplained: <b>{u['flagged']}</b>; named {escape(str(u['explained']))}; remaining "
        f"at {escape(', '.join(u['remaining_locations']))}</li>"
        for u in score["unknown"]
    )
    rel = "".join(f"<li>{escape(k)}: {v:.0%}</li>" for k, v in score["magnitude_rel_error"].items())
    null_ok, n_null = score["null_explained_empty"]
    top1, top1_explained = score["top1"], score.get("top1_explained_only")
    shrink = score["median_heldout_shrink_true"]
    return _page(
        "Blind check",
        f"""<h1>Blind check of the gap diagnosis</h1>
<p>Top-1 identification: <b>{_percent(top1)}</b> of
{score["n_effect_sessions"]} effect sessions ({_percent(top1_explained)} counting explained
effects only; an effect that opens no gap, large misalignment under the exact rotation, can
only be noted). No-effect sessions with nothing explained:
<b>{null_ok} of {n_null}</b>. Median held-out shrink of the true effect:
<b>{_percent(shrink)}</b>. Diagnosis time per session: median
{score["diagnosis_seconds"]["median"]:.0f} s, max {score["diagnosis_seconds"]["max"]:.0f} s.</p>
<h2>Confusion matrix</h2><p>Rows: hidden effect; columns: first explained effect, or with
nothing explained the first noted one, marked "(noted)", or none.</p>
<table><tr><th>hidden \\ named</th>{head}</tr>{body}</table>
<h2>Unknown-effect sessions</h2><ul>{unknown}</ul>
<h2>Relative error of the estimated magnitude (median)</h2><ul>{rel}</ul>
{_blind_detection_section(detection)}""",
    )


def _blind_detection_section(detection: Mapping | None) -> str:
    """The blind page's section on the detection sweep's limits, or why there are none."""
    if detection is None:
        return (
            "<h2>Detection limits</h2><p>No detection sweep in this folder "
            "(<code>snakemake --cores 2 detection</code>, docs/gap.md).</p>"
        )
    clean, n_clean = detection.get("clean_explained", [0, 0])
    return f"""<h2>Detection limits (detection sweep: {detection["n"]} effect sessions)</h2>
<p>The smallest magnitude named in at least {detection["criterion"]["rate"]:.0%} of the sweep's
sessions, per effect (results/detection/score.json, reports/detection.html). Clean sessions
in which an effect was explained: <b>{clean} of {n_clean}</b>.</p>
{detection_limits_table(detection)}"""


def _magnitude(value: float, unit: str) -> str:
    return f"{value:.3g} {escape(unit)}"


def detection_limits_table(score: Mapping) -> str:
    """HTML table of the detection limit of each effect of a detection sweep's score: the
    level, its magnitude (unit of the effect and SI), k/n named and the rate's lower bound."""
    confidence = score["criterion"]["confidence"]
    limits = ""
    for name, e in score["effects"].items():
        lv = e["limit"]
        if lv is None:
            note = escape(e["limit_note"])
            limits += f"<tr><th>{escape(name)}</th><td colspan=5>{note}</td></tr>"
            continue
        limits += (
            f"<tr><th>{escape(name)}</th><td>x{lv['factor']:g}</td>"
            f"<td>{_magnitude(lv['magnitude'], lv['unit'])}</td>"
            f"<td>{_magnitude(lv['magnitude_si'], lv['unit_si'])}</td>"
            f"<td>{lv['named']}/{lv['n']}</td><td>{lv['cp_lower']:.2f}</td></tr>"
        )
    return f"""<table><tr><th>effect</th><th>factor</th><th>magnitude</th>
<th>SI</th><th>named</th><th>rate, {confidence:.0%} lower bound</th></tr>{limits}</table>"""


def render_detection_page(score: Mapping) -> str:
    """The detection sweep's report page (self-contained HTML): k/n per effect and factor,
    the detection limits."""
    effects = score["effects"]
    factors = sorted({lv["factor"] for e in effects.values() for lv in e["levels"]})
    head = "".join(f"<th>x{f:g}</th>" for f in factors)
    cells = ""
    for name, e in effects.items():
        by_factor = {lv["factor"]: lv for lv in e["levels"]}
        row = ""
        for f in factors:
            lv = by_factor.get(f)
            text = "" if lv is None else f"{lv['named']}/{lv['n']}"
            if lv and lv["noted_only"]:
                text += f" (+{lv['noted_only']} noted)"
            row += f"<td>{f'<b>{text}</b>' if lv and lv['detected'] else text}</td>"
        cells += f"<tr><th>{escape(name)}</th>{row}</tr>"
    rate = score["criterion"]["rate"]
    fp, n = score["false_positive"]
    clean, n_clean = score.get("clean_explained", [0, 0])
    seconds = score.get("diagnosis_seconds")
    timing = (
        f" Diagnosis time per session: median {seconds['median']:.0f} s, max "
        f"{seconds['max']:.0f} s."
        if seconds
        else ""
    )
    return _page(
        "Detection limits",
        f"""<h1>Detection limits of the gap diagnosis</h1>
<p>{n} sessions, each with one library effect at a factor of its realistic magnitude
(docs/gap.md). A level is detected (bold) when at least ceil({rate:g} n) of its n sessions
name the effect (explained; large misalignment, which opens no gap, noted). The detection limit
is the least harsh level detected together with every harsher one (for saturation, whose
magnitude is the gyro clip level, the largest). Sessions in which another effect was explained:
<b>{fp} of {n}</b>; another effect noted: <b>{score["false_noted"][0]} of {n}</b> (a large
misalignment named by noted is to be read against it). Clean sessions (no effect) in which an
effect was explained: <b>{clean} of {n_clean}</b>. Crashes (named nothing):
{score["crashes"]}.{timing}</p>
<h2>Detection limits</h2>{detection_limits_table(score)}
<h2>Sessions naming the effect, by factor of the realistic magnitude</h2>
<p>"(+m noted)": sessions that note the effect without naming it (e.g. saturation noted by
the static fallback when the calibration chain stops).</p>
<table><tr><th>effect</th>{head}</tr>{cells}</table>""",
    )
