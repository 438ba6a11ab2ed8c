"""The stress set: sessions at the harsh end of consumer MEMS parts, diagnosed and scored.

Each session combines *conditions* (a harsh truth, slow handling, a hand-held cube, fast
platform phases: things the diagnosis has no model of, which should leave ``explained`` empty)
with *effects* of the diagnosis's library (harsh variants and the realistic library effects),
each alone and in pairs, over several seeds. The sessions are rendered like the blind check's
(:func:`imucal.gap.blind.render_blind_session`, the answer key sealed apart), diagnosed by
:func:`imucal.gap.checks.diagnose_folder`, which records a session whose pipeline or diagnosis raises as failed
with its error instead of losing the other sessions, and scored by :func:`score_stress`.
docs/gap.md lists the magnitudes and their datasheet sources.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from html import escape
from itertools import combinations

import numpy as np

from imucal.columns import SENSORS
from imucal.gap.blind import SHAPES, shape_params
from imucal.sim.effects import CANONICAL, stream_rng

#: Conditions: truth preset, protocol settings and protocol effects the diagnosis does not model.
CONDITIONS = {
    # MPU-6050 class turn-on biases: gyro up to 20 deg/s, accelerometer up to 0.6 m/s^2
    "mems_truth": {"preset": "mems"},
    # slow cube handling, 8-12 s per motion (default 2.5-3.5 s)
    "slow_handling": {"protocol": {"cube_move_s": [8.0, 12.0]}},
    # the cube held by hand: ~3 s holds with tremor and sway
    "hand_held": {"protocol": {"cube_position_s": [2.5, 3.5]}, "effects": {"hand_tremor": {}}},
    # platform phases at 300 deg/s (default 50-60): above the MPU default range of 250 deg/s
    "fast_phases": {"protocol": {"phase_rate_dps": [300.0, 300.0, 300.0]}},
}

#: Harsh variants of library effects: variant -> (effect, parameters); a ``[low, high]`` pair
#: is drawn uniformly per session.
HARSH = {
    # MPU-9250 spreads 0.24 deg/s/K and 1.5 mg/K (effects.md #1), a 10-15 K warm-up
    "temperature_harsh": ("temperature_drift", {
        "gyr_per_k": [1.75e-3, 4.4e-3], "acc_per_k": [0.0098, 0.0196], "rise_c": [10.0, 15.0],
    }),
    # rate random walk 1e-4..3e-4 rad/s/sqrt(s): 0.06-0.17 deg/s after 100 s, 0.14-0.41
    # deg/s after 10 min (rw sqrt(T)); acc 1e-4..3e-4 m/s^2/sqrt(s)
    "random_walk": ("bias_instability", {"gyr_rw": [1e-4, 3e-4], "acc_rw": [1e-4, 3e-4]}),
    "large_misalignment": ("large_misalignment", {
        "acc_deg": [4.0, 8.0], "gyr_deg": [4.0, 8.0], "mag_deg": [4.0, 8.0],
    }),
    # the MPU default ranges, 2 g and 250 deg/s: the +-300, +-400 deg/s runs clip
    "saturation_table": ("saturation", {}),
    # a 30 deg/s gyro range: the platform phases (50-60 deg/s) clip as well
    "saturation_phases": ("saturation", {"gyr": 1965}),
}  # fmt: skip

#: Library effects at their realistic magnitude (those without a harsh variant above).
REALISTIC_EFFECTS = tuple(e for e in CANONICAL if e not in {v[0] for v in HARSH.values()})

#: Effects identified when ``noted``, without a gap to attribute: one the exact model absorbs
#: (large misalignment), and clipping seen in the readings when the full twin cannot be built.
NOTED_ONLY = ("large_misalignment", "saturation")


def _draw(params: Mapping, rng: np.random.Generator) -> dict:
    return {
        k: float(rng.uniform(*v)) if isinstance(v, list) else v for k, v in sorted(params.items())
    }


def _spec(items: tuple, seed: int) -> dict:
    """A session of the stress set from its items (conditions, harsh variants, effects)."""
    preset, protocol, effects, conditions, diagnosable = "random", {}, [], [], []
    for item in items:
        if item in CONDITIONS:
            c = CONDITIONS[item]
            preset = c.get("preset", preset)
            protocol.update(c.get("protocol", {}))
            effects += [{"effect": e, "params": dict(p)} for e, p in c.get("effects", {}).items()]
            conditions.append(item)
        elif item in HARSH:
            effect, ranges = HARSH[item]
            params = _draw(ranges, stream_rng(seed, f"stress/{item}"))
            effects.append({"effect": effect, "params": params})
            diagnosable.append(effect)
        elif item in SHAPES:
            effect, params = shape_params(item, stream_rng(seed, f"stress/{item}"))
            effects.append({"effect": effect, "params": params})
            diagnosable.append(effect)
        else:
            effects.append({"effect": item, "params": {}})
            diagnosable.append(item)
    return {
        "seed": seed, "items": list(items), "conditions": conditions,
        "diagnosable": sorted(diagnosable), "preset": preset, "protocol": protocol,
        "effects": effects, "exclude": [],
        "description": "stress session (answer key sealed)",
    }  # fmt: skip


def stress_plan(seed: int, seeds_alone: int, n_clean: int) -> list[dict]:
    """The stress set's sessions, deterministic from ``seed``.

    Parameters
    ----------
    seed : int
    seeds_alone : int
        Sessions per condition or harsh variant on its own.
    n_clean : int
        Sessions without any condition or effect (the random truth, the blind protocol).

    Returns
    -------
    list of dict
        In name order (``s00``, ``s01``, ..., shuffled by the seed): ``name``, ``seed``,
        ``items`` (conditions, harsh variants, effects), ``conditions``, ``diagnosable``
        (library effects injected), ``preset``, ``protocol``, ``effects`` (simulator effects
        with parameters), ``exclude`` (empty), ``description``. Besides the clean sessions and
        the items alone: every pair of conditions and harsh variants (not two variants of one
        effect), and each realistic library effect alone and paired with one condition. The
        real parts' shapes (:data:`imucal.gap.blind.SHAPES`) alone, each temperature drift
        shape paired with the realistic g-sensitivity and with the lever arm, and the
        single-size drift with the full g-sensitivity matrix.
    """
    stress = list(CONDITIONS) + list(HARSH)
    effect_of = {k: v[0] for k, v in HARSH.items()}
    sets = [()] * n_clean + [(i,) for i in stress for _ in range(seeds_alone)]
    sets += [
        (a, b) for a, b in combinations(stress, 2)
        if a in CONDITIONS or b in CONDITIONS or effect_of[a] != effect_of[b]
    ]  # fmt: skip
    conditions = list(CONDITIONS)
    sets += [(e,) for e in REALISTIC_EFFECTS]
    sets += [(conditions[i % len(conditions)], e) for i, e in enumerate(REALISTIC_EFFECTS)]
    drifts = [v for v in SHAPES if SHAPES[v][0] == "temperature_drift"]
    sets += [(v,) for v in SHAPES for _ in range(seeds_alone)]
    sets += [(v, e) for v in drifts for e in ("g_sensitivity", "lever_arm")]
    sets += [("temperature_axes", "g_sensitivity_matrix")]
    order = stream_rng(seed, "stress/plan").permutation(len(sets))
    width = max(2, len(str(len(sets) - 1)))
    out = []
    for i, j in enumerate(order):
        session_seed = int(seed * 1000 + i)
        out.append({"name": f"s{i:0{width}d}", **_spec(sets[j], session_seed)})
    return out


def calibration_errors(calibration: Mapping, truth: Mapping) -> dict:
    """Errors of a fitted calibration against the truth, per sensor.

    Parameters
    ----------
    calibration : dict
        :meth:`ImuCalibration.to_dict` of the fit.
    truth : dict
        truth.json (per sensor ``bias`` and ``matrix``).

    Returns
    -------
    dict
        Sensor -> ``bias`` (largest |bias error| over the axes, SI: m/s^2, rad/s, normalised
        field) and ``matrix`` (largest |element| of ``M_fit M_true^-1 - I``, dimensionless:
        scale and angle errors).
    """
    out = {}
    for s in SENSORS:
        fit_m, true_m = np.asarray(calibration[s]["matrix"]), np.asarray(truth[s]["matrix"])
        bias = np.abs(np.asarray(calibration[s]["bias"]) - np.asarray(truth[s]["bias"])).max()
        matrix = np.abs(fit_m @ np.linalg.inv(true_m) - np.eye(3)).max()
        out[s] = {"bias": float(bias), "matrix": float(matrix)}
    return out


def _first_line(error: str | None) -> str:
    return (error or "").strip().splitlines()[0] if error else ""


def crash_cause(error: str) -> str:
    """An error's first line with parenthesised detail as ``(...)`` and numbers as ``#``.

    Sessions that fail for one reason differ in the numbers the message quotes (times,
    counts); the cause groups them.
    """
    line = re.sub(r"\([^()]*\)", "(...)", _first_line(error))
    return re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", line)


def is_named(effect: str, diagnosis: Mapping) -> bool:
    """The diagnosis names the effect: it is explained, or noted when it opens no gap.

    An effect of :data:`NOTED_ONLY` (``large_misalignment``, absorbed by the exact rotation;
    ``saturation``, seen in the readings when the full twin cannot be built) is named when it
    is explained or noted; every other effect when it is in ``explained``.
    """
    return effect in diagnosis.get("explained", []) or (
        effect in NOTED_ONLY and effect in diagnosis.get("noted", [])
    )


def score_stress(diagnoses: Mapping[str, Mapping], keys: Mapping[str, Mapping]) -> dict:
    """Unsealed scoring of the stress set.

    A session is **fully right** when it did not crash, every injected library effect is
    explained (or, for :data:`NOTED_ONLY`, noted) and nothing else is explained. A session
    without library effects (clean or conditions only) is right when nothing is explained; a
    crash is never right.

    Returns
    -------
    dict
        ``n``, ``crashes`` (count), ``fully_right`` ([k, n]), ``fully_right_fraction``,
        ``null_explained_empty`` ([k, n] over the sessions without library effects),
        ``by_item`` (condition, harsh variant or effect -> n, crashed, fully_right),
        ``crash_groups`` (:func:`crash_cause` -> session names), ``crash_where`` (innermost
        package frame -> session names), ``calibration_error_median`` (sensor -> bias, matrix
        over the sessions with a calibration), ``sessions`` (the detail).
    """
    sessions, by_item, groups, where, errors = [], {}, {}, {}, {s: [] for s in SENSORS}
    right = n_null = null_ok = crashes = 0
    for name in sorted(keys):
        key, diag = keys[name], diagnoses[name]
        spec = key["spec"]
        injected = set(spec["diagnosable"])
        explained, noted = list(diag.get("explained", [])), list(diag.get("noted", []))
        crashed = diag.get("failed") is not None
        found = {e for e in injected if is_named(e, diag)}
        extra = sorted(set(explained) - injected)
        ok = not crashed and found == injected and not extra
        row = {
            "name": name, "items": spec["items"], "conditions": spec["conditions"],
            "injected": sorted(injected), "crashed": crashed,
            "error": _first_line(diag.get("failed")), "failed_in": diag.get("failed_in"),
            "where": diag.get("where"), "stages_not_run": list(diag.get("pipeline_notes", [])),
            "explained": explained, "noted": noted, "missed": sorted(injected - found),
            "extra": extra, "fully_right": ok,
            "gap_significant": diag["gap"]["significant"],
            "remaining_significant": diag["remaining"]["significant"],
        }  # fmt: skip
        if diag.get("calibration") is not None:
            row["calibration_error"] = calibration_errors(diag["calibration"], key["truth"])
            for s in SENSORS:
                errors[s].append(row["calibration_error"][s])
        crashes += crashed
        right += ok
        if not injected:
            n_null += 1
            null_ok += not crashed and not explained
        if crashed:
            groups.setdefault(crash_cause(row["error"]), []).append(name)
            where.setdefault(row["where"] or "(outside the package)", []).append(name)
        for item in spec["items"] or ["clean"]:
            b = by_item.setdefault(item, {"n": 0, "crashed": 0, "fully_right": 0})
            b["n"] += 1
            b["crashed"] += crashed
            b["fully_right"] += ok
        sessions.append(row)
    n = len(sessions)
    median = {
        s: {k: float(np.median([e[k] for e in v])) for k in ("bias", "matrix")}
        for s, v in errors.items()
        if v
    }
    return {
        "n": n,
        "crashes": crashes,
        "fully_right": [right, n],
        "fully_right_fraction": right / n if n else None,
        "null_explained_empty": [null_ok, n_null],
        "by_item": dict(sorted(by_item.items())),
        "crash_groups": dict(sorted(groups.items(), key=lambda kv: -len(kv[1]))),
        "crash_where": dict(sorted(where.items(), key=lambda kv: -len(kv[1]))),
        "calibration_error_median": median,
        "sessions": sessions,
    }


def render_stress_page(score: Mapping) -> str:
    """The stress set's report page (self-contained HTML)."""
    items = "".join(
        f"<tr><th>{escape(k)}</th><td>{v['n']}</td><td>{v['crashed']}</td>"
        f"<td>{v['fully_right']}</td></tr>"
        for k, v in score["by_item"].items()
    )
    groups = "".join(
        f"<li><code>{escape(err)}</code>: {len(names)} ({escape(', '.join(names))})</li>"
        for err, names in score["crash_groups"].items()
    )
    cal = "".join(
        f"<tr><th>{escape(s)}</th><td>{v['bias']:.3g}</td><td>{v['matrix']:.3g}</td></tr>"
        for s, v in score["calibration_error_median"].items()
    )
    rows = "".join(
        f"<tr><td>{escape(r['name'])}</td><td>{escape(' + '.join(r['items']) or 'clean')}</td>"
        f"<td>{'crash' if r['crashed'] else ''}</td><td>{escape(', '.join(r['explained']))}</td>"
        f"<td>{escape(', '.join(r['noted']))}</td><td>{'yes' if r['fully_right'] else ''}</td>"
        f"<td>{escape(r['error'])}</td></tr>"
        for r in score["sessions"]
    )
    right, n = score["fully_right"]
    null_ok, n_null = score["null_explained_empty"]
    seconds = score.get("diagnosis_seconds", {})
    timing = (
        f" Diagnosis time per session: median {seconds['median']:.0f} s, max {seconds['max']:.0f} s."
        if seconds
        else ""
    )
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>Stress set</title>
<style>body{{font-family:sans-serif;max-width:72em;margin:auto}}td,th{{border:1px solid #ccc;
padding:2px 6px}}table{{border-collapse:collapse}}</style></head><body>
<h1>Stress set of the gap diagnosis</h1>
<p>{n} sessions at the harsh end of consumer MEMS parts (docs/gap.md). Crashes:
<b>{score["crashes"]}</b>. Fully right (every injected library effect explained, or noted for
large misalignment, and nothing else): <b>{right} of {n}</b>. Sessions without library effects
with nothing explained: <b>{null_ok} of {n_null}</b>.{timing}</p>
<h2>By condition and effect</h2><table><tr><th>item</th><th>sessions</th><th>crashed</th>
<th>fully right</th></tr>{items}</table>
<h2>Crashes by error</h2><ul>{groups}</ul>
<h2>Calibration error against the truth (median over the sessions with a calibration)</h2>
<table><tr><th>sensor</th><th>|bias error| (SI)</th><th>|M_fit M_true^-1 - I|</th></tr>{cal}
</table>
<h2>Sessions</h2><table><tr><th>session</th><th>items</th><th>crash</th><th>explained</th>
<th>noted</th><th>fully right</th><th>error</th></tr>{rows}</table>
</body></html>
"""
