"""The lab report's section on temperature terms held out across static poses.

Context of ``templates/_holdout.html.j2`` from ``results/{dataset}/temperature_holdout.json``
(:func:`imucal.terms.poseholdout.hold_out_recording`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

from imucal.io import read_json

#: Display unit per sensor: (label, factor from the SI unit of the JSON).
DISPLAY_UNITS = {
    "gyr": ("mdeg/s", 180.0 / math.pi * 1e3),
    "acc": ("mm/s^2", 1e3),
    "mag": ("1e-3 field norm", 1e3),
}


def _number(value: float, digits: int) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def holdout_section(path: str | Path | None) -> dict | None:
    """Context of the temperature hold-out partial, None without a hold-out.

    Returns
    -------
    dict or None
        ``reason`` (the stage did not run) or ``rows`` (per held-out pose, sensor and axis:
        the three residual RMS in display units with their standard errors over long blocks,
        the ratios to none and of the term to the regression with their 95 % intervals (with
        the fits' scatter; for the term against the regression also given the fits), the
        two verdicts, the order and the compared fraction), ``summary`` (the same over all held-out
        poses), ``units``, ``settings``, ``poses``, ``warnings``.
    """
    if path is None:
        return None
    from imucal.pipeline.outcome import not_run_reason

    d = read_json(path)
    reason = not_run_reason(d)
    if reason:
        return {"reason": reason}

    def row(c: Mapping, label: str) -> dict:
        factor = DISPLAY_UNITS[c["sensor"]][1]

        def rms(method: str) -> str:
            value = _number(factor * c[f"rms_{method}"], 2)
            return f"{value} ± {_number(factor * c[f'rms_{method}_se'], 2)}"

        def ratio(name: str, digits: int = 3, interval: str = "ci95") -> str:
            lo, hi = c.get(f"{name}_{interval}", [math.nan, math.nan])
            return f"{_number(c[name], digits)} ({_number(lo, digits)}-{_number(hi, digits)})"

        return {
            "pose": label,
            "sensor": c["sensor"],
            "axis": c["axis"],
            "order": c.get("order", ", ".join(str(o) for o in c.get("orders", []))),
            "none": rms("none"),
            "term": rms("term"),
            "regression": rms("regression"),
            "term_ratio": ratio("term_ratio"),
            "regression_ratio": ratio("regression_ratio"),
            "term_vs_regression": ratio("term_vs_regression", 4),
            "given_fits": ratio("term_vs_regression", 4, "ci95_given_fits"),
            "verdict": c["verdict"],
            "verdict_given_fits": c.get("verdict_given_fits", "-"),
            "fraction": _number(c.get("fraction", math.nan), 2),
        }

    return {
        "reason": None,
        "recording": d["recording"],
        "settings": d["settings"],
        "poses": [
            {
                "label": p["label"],
                "samples": p["samples"],
                "span": f"{p['temp_span_c'][0]:.1f}-{p['temp_span_c'][1]:.1f}",
            }
            for p in d["poses"]
        ],  # fmt: skip
        "rows": [row(c, c["held_out"]) for c in d["cells"]],
        "summary": [row(s, "all") for s in d["summary"]],
        "units": {s: DISPLAY_UNITS[s][0] for s in d["sensors"]},
        "warnings": d.get("warnings", []),
    }
