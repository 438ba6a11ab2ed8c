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
        every method's residual RMS in display units with its standard error over long
        blocks, the ratios to none and of the term to each peer with their 95 % intervals
        (with the fits' scatter, and given the fits) and verdicts, whether the term is taken,
        its flags, the order and the compared fraction), ``summary`` (the same over all
        held-out poses), ``methods`` and ``peers``, ``flagged`` (the rows with a flag),
        ``shipped`` (per sensor and axis, the term that ships or why not), ``units``,
        ``settings``, ``poses``, ``warnings``.
    """
    if path is None:
        return None
    from imucal.pipeline.outcome import not_run_reason

    d = read_json(path)
    reason = not_run_reason(d)
    if reason:
        return {"reason": reason}

    peers = [m for m in d.get("methods", {}) if m not in ("none", "term")]

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
            "rms": [rms(m) for m in ("none", "term", *peers)],
            "ratios": [ratio(f"{m}_ratio") for m in ("term", *peers)],
            "versus": [
                f"{ratio(f'term_vs_{p}', 4)} {c['verdicts'][p]}; given the fits "
                + "-".join(_number(v, 4) for v in c[f"term_vs_{p}_ci95_given_fits"])
                for p in peers
            ],
            "taken": "yes" if c["taken"] else "no",
            "flags": c["flags"],
            "fraction": _number(c.get("fraction", math.nan), 2),
        }

    rows = [row(c, c["held_out"]) for c in d["cells"]]
    summary = [row(s, "all") for s in d["summary"]]
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
        "rows": rows,
        "summary": summary,
        "methods": d["methods"],
        "peers": peers,
        "flagged": [r for r in summary + rows if r["flags"]],
        "shipped": d.get("shipped", []),
        "units": {s: DISPLAY_UNITS[s][0] for s in d["sensors"]},
        "warnings": d.get("warnings", []),
    }
