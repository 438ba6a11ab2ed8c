"""Figures and template context of the report's gap section (figures are returned, never saved).

* :func:`plot_gap_map`: heat map of the scores, locations (stage / sensor / axis / segment) by
  statistic, in a colour-blind-safe diverging map (``cividis`` of |z| on a log scale, the sign
  printed in the cell);
* :func:`plot_effects`: the ranked effects, gap before and after adding each to the twin, in
  sample and held out.
"""

from __future__ import annotations

from collections.abc import Mapping
from html import escape
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn: the report's context needs none
    from matplotlib.figure import Figure


def _percent(x) -> str:
    """A share as a percentage, or 'n/a' when it is undefined (no gap to close)."""
    return "n/a" if x is None else f"{x:.0%}"


def plot_gap_map(diagnosis: Mapping) -> Figure:
    """Heat map of |z| per location (rows: stage/sensor/axis/segment, columns: statistic)."""
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    locs = diagnosis["all_locations"]
    rows = sorted({(d["stage"], d["sensor"], d["axis"], d["segment"]) for d in locs})
    cols = sorted({d["statistic"] for d in locs})
    z = np.full((len(rows), len(cols)), np.nan)
    flag = np.zeros(z.shape, dtype=bool)
    for d in locs:
        i = rows.index((d["stage"], d["sensor"], d["axis"], d["segment"]))
        j = cols.index(d["statistic"])
        z[i, j], flag[i, j] = d["z"], d["in_gap"]
    # at most 10 in wide: saved at 110 dpi it fits the report's page without being scaled
    # down, so that the 8-point labels stay readable (about 12 px)
    fig = Figure(figsize=(min(10, max(6, 0.4 * len(cols) + 4)), max(4, 0.2 * len(rows) + 2.5)))
    ax = fig.add_subplot()
    a = np.abs(z)
    im = ax.imshow(np.where(np.isfinite(a), np.maximum(a, 0.1), np.nan), cmap="cividis",
                   norm=LogNorm(0.1, max(10.0, np.nanmax(a) if np.isfinite(a).any() else 10)),
                   aspect="auto")  # fmt: skip
    for i, j in zip(*np.where(flag), strict=True):
        ax.text(j, i, "+" if z[i, j] > 0 else "-", ha="center", va="center", color="red",
                fontsize=9, fontweight="bold")  # fmt: skip
    ax.set_xticks(range(len(cols)), cols, rotation=60, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), ["/".join(r) for r in rows], fontsize=8)
    ax.set_xlabel("statistic")
    ax.set_ylabel("stage / sensor / axis / segment")
    fig.colorbar(im, ax=ax, label="|z| against the twin's null (marked: in the gap, Holm)")
    ax.set_title(f"Gap map of {diagnosis['dataset']}")
    fig.tight_layout()
    return fig


def plot_effects(diagnosis: Mapping) -> Figure:
    """Gap before and after each evaluated effect, in sample and held out (symlog scale)."""
    from matplotlib.figure import Figure

    ev = [e for e in diagnosis["effects"] if e["evaluated"]]
    fig = Figure(figsize=(7, 1.2 + 0.5 * max(len(ev), 1)))
    ax = fig.add_subplot()
    if not ev:
        ax.text(0.5, 0.5, "no effect's estimate was outside the null", ha="center",
                va="center", transform=ax.transAxes)  # fmt: skip
        ax.set_axis_off()
        return fig
    y = np.arange(len(ev))
    ax.barh(y - 0.2, [e["gap_before"] for e in ev], 0.4, color="#999999", label="gap before")
    ax.barh(y + 0.2, [e["gap_after"] for e in ev], 0.4, color="#0072B2", label="gap after")
    for i, e in enumerate(ev):
        ax.text(e["gap_before"], i - 0.2, f"  shrink {_percent(e['shrink'])}, held out "
                f"{_percent(e['heldout_shrink'])}{' (accepted)' if e['accepted'] else ''}",
                va="center", fontsize=7)  # fmt: skip
    ax.axvline(diagnosis["gap"]["null_p95"], color="#D55E00", ls="--", label="null 95 %")
    ax.set_xscale("symlog", linthresh=1.0)  # a gap closed entirely is 0
    ax.set_yticks(y, [e["name"] for e in ev])
    ax.set_xlabel("total gap (squared scores beyond what noise gives)")
    ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(0, 1.0), ncol=3, frameon=False)
    fig.tight_layout()
    return fig


def verdict(diagnosis: Mapping) -> str:
    """The diagnosis's verdict in one sentence (:func:`imucal.gap.scoring.verdict_of`), or
    the summary for a diagnosis.json written before verdicts were."""
    found = diagnosis.get("verdict")
    return found["sentence"] if found else summary(diagnosis)


def summary(diagnosis: Mapping) -> str:
    """A plain-language summary of the diagnosis: where the gap lies, what explains it."""
    gap = diagnosis["gap"]
    if not gap["significant"]:
        return ("The session behaves like its twin: no location is outside what noise alone "
                f"gives (total gap {gap['total']:.0f}, null 95 % {gap['null_p95']:.0f}).")  # fmt: skip
    top = ", ".join(f"{d['stage']}/{d['sensor']}/{d['axis']} {d['statistic']} (z = {d['z']:.3g})"
                    for d in diagnosis["locations"][:3])  # fmt: skip
    text = (f"The session departs from its twin at {len(diagnosis['locations'])} location(s), "
            f"most at {top}; total gap {gap['total']:.3g} against a null 95 % of "
            f"{gap['null_p95']:.3g}. ")  # fmt: skip
    acc = [e for e in diagnosis["effects"] if e["accepted"]]
    if acc:
        text += "Explained by " + "; then ".join(
            f"{e['name']} ({_params(e['params'])}: held-out shrink {e['heldout_shrink']:.0%})"
            for e in acc) + ". "  # fmt: skip
    rem = diagnosis["remaining"]
    if rem["significant"]:
        where = ", ".join(f"{d['stage']}/{d['sensor']}/{d['axis']} {d['statistic']}"
                          for d in rem["locations"][:3])  # fmt: skip
        text += f"A significant gap remains unexplained at {where}."
    else:
        text += "The gap left is within what noise alone gives."
    return text


def _params(params: Mapping) -> str:
    return ", ".join(
        f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in params.items()
    )


def observations_context(diagnosis: Mapping) -> dict:
    """What the diagnosis says besides the gap (any scope): why the full diagnosis could not
    run, what it noted, which recordings were held by hand, which rest stands in for a static
    recording."""
    return {
        "fallback": diagnosis.get("fallback"),
        "held_by_hand": diagnosis.get("held_by_hand", []),
        "noted": diagnosis.get("noted", []),
        "saturation": diagnosis.get("saturation"),
        "static_source": diagnosis.get("static_source"),
    }


def report_context(diagnosis: Mapping, figures: Mapping[str, str]) -> dict:
    """Context of the ``_gap.html.j2`` partial: verdict, tables, embedded figure data."""
    return {
        **observations_context(diagnosis),
        "verdict": verdict(diagnosis),
        "outcome": (diagnosis.get("verdict") or {}).get("outcome"),
        "summary": summary(diagnosis),
        "gap": diagnosis["gap"],
        "locations": diagnosis["locations"][:20],
        "effects": diagnosis["effects"],
        "explained": diagnosis["explained"],
        "remaining": diagnosis["remaining"],
        "confusable": diagnosis.get("confusable", []),
        "null": diagnosis.get("null", {}),
        "figures": dict(figures),
    }


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
