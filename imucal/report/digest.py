"""What the lab report shows first and in its tables: the headline per sensor (what was
calibrated, how well, on what basis, with which warnings), and the stage results and the
validation as tables with units (the gap verdict's sentence: :mod:`imucal.report.gapsection`).

The raw JSON files stay the full record (the report links them); these tables pick the figures
a lab user reads, each with its unit. A key a stage does not write is left out, so a table holds
what the run produced and nothing is invented.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from imucal.columns import AXES
from imucal.report.numbers import format_number

#: Unit of each sensor's calibrated output.
SENSOR_UNITS = {"acc": "m/s²", "gyr": "rad/s", "mag": "normalised"}
SENSOR_TITLES = {"mag": "Magnetometer", "acc": "Accelerometer", "gyr": "Gyroscope"}
#: Averaging windows of the orientation check against a declared reference (reference/validation).
ORIENTATION_WINDOWS = ("1s", "10s", "30s")


def _fmt(value: Any, digits: int = 4) -> str:
    return format_number(value, digits)


def _get(node: Any, *path: str) -> Any:
    for key in path:
        if not isinstance(node, Mapping) or key not in node:
            return None
        node = node[key]
    return node


def _rms(values: Any) -> float | None:
    if values is None:
        return None
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else None


def _row(quantity: str, value: Any, unit: str = "", std: Any = None, digits: int = 4) -> dict:
    """A table row: a scalar spans the three axis columns, a 3-vector fills them."""
    if (
        isinstance(value, (list, tuple, np.ndarray))
        and len(value) == 3
        and all(v is None or isinstance(v, (int, float, np.number)) for v in value)
    ):
        sd = std if isinstance(std, (list, tuple, np.ndarray)) and len(std) == 3 else None
        cells = [
            _fmt(v, digits) if sd is None or sd[i] is None else
            f"{_fmt(v, digits)} ± {_fmt(sd[i], 2)}"
            for i, v in enumerate(value)
        ]  # fmt: skip
        return {"quantity": quantity, "cells": cells, "unit": unit, "note": "", "link": None}
    text = value if isinstance(value, str) else _fmt(value, digits)
    if std is not None and not isinstance(value, str):
        text = f"{text} ± {_fmt(std, 2)}"
    return {"quantity": quantity, "cells": [text], "unit": unit, "note": "", "link": None}


def _table(title: str, rows: Sequence[dict | None]) -> dict | None:
    kept = [r for r in rows if r is not None]
    if not kept:
        return None
    vector = any(len(r["cells"]) == 3 for r in kept)  # else one value column, no x, y, z
    return {"title": title, "kind": "rows", "rows": kept, "vector": vector}


def _maybe(quantity: str, value: Any, unit: str = "", std: Any = None, digits: int = 4):
    return None if value is None else _row(quantity, value, unit, std, digits)


# --------------------------------------------------------------------------------------------
# Stage results


def _ellipsoid(step1: Mapping) -> dict | None:
    used = step1.get("used")
    fit = _get(step1, "lm") if used and "lm" in str(used) else _get(step1, "svd")
    return _table(
        "Step 1: ellipsoid fit (magnetometer readings onto the unit sphere)",
        [
            _maybe("method", used),
            _maybe("recording fitted", step1.get("source")),
            _maybe("samples", step1.get("n_samples")),
            _maybe("sphere coverage", step1.get("coverage_pct"), "%"),
            _maybe("condition number", step1.get("condition_number")),
            _maybe("residual | |m| − 1 | RMS", _get(fit, "residual_rms"), "normalised"),
        ],
    )


def _alignment(step2: Mapping, unit: str, label: str) -> dict | None:
    used = step2.get("used")
    fit = _get(step2, str(used)) if used else None
    if not isinstance(fit, Mapping):
        return None
    residual = fit.get("residual_rms") or {}
    skipped = fit.get("skipped") or {}
    return _table(
        f"Step 2: alignment T_R of the {label} (phases about x, y, z)",
        [
            _maybe("method", used),
            _maybe("misalignment α", fit.get("alpha_rad"), "rad", fit.get("std_alpha_rad")),
            _row("residual RMS per phase", [residual.get(a) for a in AXES], unit)
            if residual
            else None,
            _maybe(
                "phases not used",
                "; ".join(f"{a}: {why}" for a, why in skipped.items()) if skipped else None,
            ),
        ],
    )


def _cube(step1: Mapping) -> dict | None:
    n = step1.get("n_samples")
    return _table(
        "Step 1: cube fit (static positions against gravity)",
        [
            _maybe("positions", len(step1["labels"]) if step1.get("labels") else None),
            _maybe(
                "samples per position",
                f"{min(n)} to {max(n)}" if isinstance(n, list) and n else n,
            ),
            _maybe(
                "|a| − g RMS over the positions, before",
                _rms(step1.get("magnitude_error_before_m_s2")),
                "m/s²",
            ),
            _maybe(
                "|a| − g RMS over the positions, after",
                _rms(step1.get("magnitude_error_after_m_s2")),
                "m/s²",
            ),
            _maybe("noise std per axis", step1.get("noise_std_m_s2"), "m/s²"),
            _maybe(
                "χ² / degrees of freedom",
                f"{_fmt(step1['chi2'], 3)} / {step1['dof']}"
                if step1.get("chi2") is not None and step1.get("dof") is not None
                else None,
            ),
            _maybe("gravity used", step1.get("gravity_m_s2"), "m/s²"),
        ],
    )


def _gyroscope(result: Mapping) -> list[dict | None]:
    used = result.get("used")
    tables = []
    rows = [_maybe("method used", used)]
    for name, label in (("tool_free", "tool-free (eq. 36)"), ("ratetable", "rate table (eq. 33)")):
        block = result.get(name)
        if isinstance(block, Mapping):
            rows.append(_maybe(f"scale s, {label}", block.get("scale"), "1",
                               _get(block, "std", "scale"), 6))  # fmt: skip
            rows.append(_maybe(f"bias o, {label}", block.get("bias"), "rad/s",
                               _get(block, "std", "bias")))  # fmt: skip
    tables.append(_table("Gyroscope fits compared", rows))
    bias = result.get("gyr_bias")
    if isinstance(bias, Mapping):
        tables.append(
            _table(
                "Gyroscope bias from the resting intervals",
                [
                    _maybe(
                        "bias (least squares)",
                        bias.get("bias_ls_rad_s"),
                        "rad/s",
                        bias.get("std_ls_rad_s"),
                    ),  # fmt: skip
                    _maybe(
                        "bias (mean)",
                        bias.get("bias_mean_rad_s"),
                        "rad/s",
                        bias.get("std_mean_rad_s"),
                    ),  # fmt: skip
                    _maybe("noise std per axis", bias.get("noise_std_rad_s"), "rad/s"),
                    _maybe("resting intervals", bias.get("n_segments")),
                    _maybe("samples", bias.get("n_samples")),
                ],
            )
        )
    ref = result.get("gyr_reference")
    if isinstance(ref, Mapping):
        tables.append(
            _table(
                "Gyroscope against the orientation reference",
                [
                    _maybe("recordings fitted", ", ".join(ref.get("recordings") or []) or None),
                    _maybe("mounting of the reference", _get(ref, "mounting", "angle_deg"), "°"),
                    _maybe("rate residual RMS per axis", ref.get("residual_rms_rad_s"), "rad/s"),
                    _maybe("intervals used", ref.get("n_intervals")),
                    _maybe("outliers left out", ref.get("n_outliers")),
                ],
            )
        )
    return tables


def stage_tables(sensor: str, result: Mapping | None) -> list[dict]:
    """Tables of one sensor's stage results (``mag.json``, ``acc.json``, ``gyr.json``, full or
    partial), each ``{title, rows: [{quantity, cells (1 or 3 strings), unit}]}``."""
    if not result:
        return []
    tables: list[dict | None] = []
    if sensor == "mag":
        for key in ("step1", "mag_step1"):
            if isinstance(result.get(key), Mapping):
                tables.append(_ellipsoid(result[key]))
        if isinstance(result.get("step2"), Mapping):
            tables.append(_alignment(result["step2"], "normalised", "magnetometer"))
        ref = result.get("mag_reference")
        if isinstance(ref, Mapping):
            tables.append(
                _table(
                    "Step 2: alignment T_R against the orientation reference",
                    [
                        _maybe(
                            "misalignment α", ref.get("alpha_rad"), "rad", ref.get("alpha_std_rad")
                        ),  # fmt: skip
                        _maybe(
                            "field direction error, median", ref.get("residual_median_deg"), "°"
                        ),  # fmt: skip
                        _maybe(
                            "field direction error, 95th percentile",
                            ref.get("residual_p95_deg"),
                            "°",
                        ),  # fmt: skip
                        _maybe("samples", ref.get("n_samples")),
                    ],
                )
            )
    elif sensor == "acc":
        if isinstance(result.get("step1"), Mapping):
            tables.append(_cube(result["step1"]))
        if isinstance(result.get("step2"), Mapping):
            tables.append(_alignment(result["step2"], "m/s²", "accelerometer"))
    elif sensor == "gyr":
        tables += _gyroscope(result)
    return [t for t in tables if t is not None]


# --------------------------------------------------------------------------------------------
# Validation


def _offset_note(offset_s: float) -> str:
    """What a time offset of the reference's clock (``t_ref = offset + t_module``) means."""
    more = "more" if offset_s > 0 else "less"
    if abs(offset_s) >= 1.0:
        return (
            f"at the same instant the reference's clock reads {_fmt(abs(offset_s))} s {more} "
            "than the module's: the two recordings were started that far apart; removed before "
            "the comparison"
        )
    return (
        f"at the same instant the reference's clock reads {_fmt(abs(offset_s) * 1e3)} ms {more} "
        "than the module's (a latency between the two streams); removed before the comparison"
    )


def _angle_row(name: str, dip: Mapping | None) -> dict | None:
    """The angle between specific force and field of one source, with the dip it implies."""
    mean = _get(dip, "mean_deg")
    row = _maybe(f"angle, {name}", mean, "°", _get(dip, "std_deg"))
    if row is not None and mean is not None and np.isfinite(mean):
        row["note"] = f"dip {_fmt(float(mean) - 90.0)}° (the angle less 90°)"
    return row


def validation_tables(validation: Mapping | None, reconciled: Mapping | None = None) -> list[dict]:
    """Tables of validation.json (full protocol: ``metrics``) or of reference/validation.json
    (declared orientation references: ``summary``); ``reconciled``, the reference's clock offset
    reconciled with the gap diagnosis (:func:`imucal.report.gapsection.reconcile_offset`),
    links the two."""
    if not validation:
        return []
    tables: list[dict | None] = []
    metrics = validation.get("metrics")
    if isinstance(metrics, Mapping) and isinstance(metrics.get("calibrated"), Mapping):
        rows = []
        for sensor in ("acc", "gyr", "mag"):
            raw = _get(metrics, "raw", sensor) or {}
            cal = _get(metrics, "calibrated", sensor)
            if not isinstance(cal, Mapping):
                continue
            unit = SENSOR_UNITS[sensor]
            for key, what, u in (
                ("rms_norm_diff", "|v| − |v_ref| RMS", unit),
                ("rms_diff", "|v − v_ref| RMS", unit),
                ("rms_angle_deg", "direction error RMS", "°"),
            ):
                if key in cal:
                    rows.append({"sensor": SENSOR_TITLES[sensor], "quantity": what,
                                 "raw": _fmt(raw.get(key)), "calibrated": _fmt(cal[key]),
                                 "unit": u, "n": _fmt(cal.get("n"))})  # fmt: skip
        if rows:
            tables.append({"title": "The module against the reference, before and after "
                           "calibration", "kind": "compare", "rows": rows})  # fmt: skip
        time = validation.get("time_alignment") or {}
        mount = validation.get("mounting") or {}
        offset = None
        if time.get("offset_s") is not None:
            offset = {**_row("time offset of the reference's clock", time["offset_s"], "s",
                             time.get("offset_std_s"), 6),
                      "note": _offset_note(float(time["offset_s"]))}  # fmt: skip
            if reconciled:
                offset["note"] = (
                    f"the reference's clock reads {reconciled['validation_s']} s at the "
                    f"module's first sample and {reconciled['first_stamp_s']} s at its own "
                    f"first sample: it started {reconciled['lead_s']} s before the module; "
                    "removed before the comparison"
                )
                if reconciled["diagnosis_s"] is not None:
                    offset["link"] = {"href": "#gap",
                                      "text": "the time offset of the sim-to-real gap"}  # fmt: skip
        tables.append(
            _table(
                "Alignment of the reference to the module (removed before the comparison)",
                [
                    offset,
                    _maybe("clock drift", time.get("drift_ppm"), "ppm", time.get("drift_std_ppm")),
                    _maybe("correlation of the rates", time.get("correlation"), "", None, 6),
                    _maybe(
                        "mounting rotation of the reference",
                        mount.get("angle_deg"),
                        "°",
                        mount.get("angle_std_deg"),
                    ),  # fmt: skip
                ],
            )
        )
        dip = validation.get("dip") or {}
        if dip:
            tables.append(
                _table(
                    "Angle between the specific force and the magnetic field at rest (90° plus "
                    "the field's dip below the horizontal; its spread over the rests checks "
                    "the accelerometer against the magnetometer)",
                    [
                        _angle_row(name, dip.get(name))
                        for name in ("raw", "calibrated", "reference")
                    ],
                )
            )
    summary = validation.get("summary")
    if isinstance(summary, Mapping):
        rows = []
        for name, s in summary.items():
            for window in ORIENTATION_WINDOWS:
                err = s.get(f"orientation_median_deg_{window}")
                if not isinstance(err, Mapping):
                    continue
                rows.append({
                    "recording": name,
                    "held_out": "held out" if s.get("held_out") else "used by the fit",
                    "window": window.replace("s", " s"),
                    "raw": _fmt(err.get("raw"), 3),
                    "bias": _fmt(err.get("bias"), 3),
                    "calibrated": _fmt(err.get("calibrated"), 3),
                    "transfer": (s.get("transfer") or {}).get(window, ""),
                })  # fmt: skip
        if rows:
            tables.append({"title": "Orientation error integrated from the gyroscope over "
                           "windows, median against the reference", "kind": "orientation",
                           "rows": rows})  # fmt: skip
        align = []
        for name, s in summary.items():
            if s.get("offset_ms") is not None:
                align.append({**_row(f"{name}: time offset of the reference", s["offset_ms"],
                                     "ms", s.get("offset_std_ms")),
                              "note": _offset_note(float(s["offset_ms"]) / 1e3)})  # fmt: skip
            align.append(_maybe(f"{name}: clock drift", s.get("drift_ppm"), "ppm"))
            align.append(_maybe(f"{name}: mounting of the reference", s.get("mounting_deg"), "°"))
        tables.append(_table("Alignment of the references (removed before the comparison)",
                             align))  # fmt: skip
    return [t for t in tables if t is not None]


# --------------------------------------------------------------------------------------------
# Headline


def _held_out(sensor: str, validation: Mapping | None) -> tuple[list[str], str] | None:
    """Sentences of the held-out figures of one sensor against the reference, and their basis."""
    if not validation:
        return None
    cal = _get(validation, "metrics", "calibrated", sensor)
    raw = _get(validation, "metrics", "raw", sensor) or {}
    if isinstance(cal, Mapping):
        unit = SENSOR_UNITS[sensor]
        lines = []
        if "rms_norm_diff" in cal:
            lines.append(f"magnitude error |v| − |v_ref| RMS {_fmt(raw.get('rms_norm_diff'), 3)}"
                         f" → {_fmt(cal['rms_norm_diff'], 3)} {unit}")  # fmt: skip
        if "rms_angle_deg" in cal:
            lines.append(f"direction error RMS {_fmt(raw.get('rms_angle_deg'), 3)} → "
                         f"{_fmt(cal['rms_angle_deg'], 3)}°")  # fmt: skip
        return lines, (
            "against the reference recording (raw → calibrated), after time alignment and mounting"
        )
    summary = validation.get("summary")
    if sensor == "gyr" and isinstance(summary, Mapping):
        held = {n: s for n, s in summary.items() if s.get("held_out")}
        lines = []
        for name, s in (held or summary).items():
            err = s.get("orientation_median_deg_10s")
            if isinstance(err, Mapping):
                lines.append(
                    f"{name}: orientation error over 10 s, median {_fmt(err.get('raw'), 3)}° raw, "
                    f"{_fmt(err.get('bias'), 3)}° with the bias only, "
                    f"{_fmt(err.get('calibrated'), 3)}° calibrated"
                    + (
                        f" (calibrated against the bias only: {s['transfer']['10s']})"
                        if _get(s, "transfer", "10s")
                        else ""
                    )
                )
        if lines:
            basis = ("against the held-out orientation reference" if held else
                     "against the orientation reference the fit used (not held out)")  # fmt: skip
            return lines, basis
    return None


def _fallback(sensor: str, result: Mapping | None) -> tuple[list[str], str] | None:
    """Reference-free figures of one sensor from its stage results (in-sample)."""
    if not result:
        return None
    if sensor == "acc":
        step1 = result.get("step1") or {}
        before = _rms(step1.get("magnitude_error_before_m_s2"))
        after = _rms(step1.get("magnitude_error_after_m_s2"))
        if after is not None:
            return ([f"|a| − g RMS at the cube positions {_fmt(before, 3)} → {_fmt(after, 3)} m/s²"],
                    "reference-free: at the positions the fit used (in-sample)")  # fmt: skip
    if sensor == "mag":
        ref = result.get("mag_reference") or {}
        if ref.get("residual_median_deg") is not None:
            return ([f"field direction error median {_fmt(ref['residual_median_deg'], 3)}°, "
                     f"95th percentile {_fmt(ref.get('residual_p95_deg'), 3)}°"],
                    "against the orientation reference the fit used (in-sample)")  # fmt: skip
        step1 = result.get("step1") or result.get("mag_step1") or {}
        fit = step1.get("lm") if "lm" in str(step1.get("used", "")) else step1.get("svd")
        if _get(fit, "residual_rms") is not None:
            return ([f"| |m| − 1 | RMS after the ellipsoid fit {_fmt(fit['residual_rms'], 3)} "
                     "(normalised)"], "reference-free: on the samples the fit used (in-sample)")  # fmt: skip
    if sensor == "gyr":
        ref = result.get("gyr_reference") or {}
        if ref.get("residual_rms_rad_s") is not None:
            cells = ", ".join(_fmt(v, 3) for v in ref["residual_rms_rad_s"])
            return ([f"rate residual RMS x, y, z {cells} rad/s"],
                    "against the orientation reference the fit used (in-sample)")  # fmt: skip
    return None


#: Characters of a warning in the summary (the Warnings section has it whole).
WARNING_CHARS = 90


def merged_warnings(warnings: Sequence[Mapping]) -> list[dict]:
    """The run's warnings with one entry per message: the same text from several sources (a
    rule's log and another's) counted once, with its sources; in order of first appearance.

    Returns
    -------
    list of dict
        ``text``, ``count`` (summed over the sources), ``sources`` and ``summary`` (the short
        form, with the count).
    """
    merged: dict[str, dict] = {}
    for w in warnings:
        entry = merged.setdefault(
            str(w["text"]), {**dict(w), "text": str(w["text"]), "count": 0, "sources": []}
        )
        entry["count"] += int(w.get("count", 1))
        if w.get("source") not in entry["sources"]:
            entry["sources"].append(w.get("source"))
    for entry in merged.values():
        entry["summary"] = short_warning(entry)
    return list(merged.values())


def short_warning(warning: Mapping) -> str:
    """A warning for the summary: its first clause, ``(39 times)`` when a log repeats it."""
    count = int(warning.get("count", 1))
    return _short(str(warning["text"])) + (f" ({count} times)" if count > 1 else "")


def _short(text: str) -> str:
    """A warning's first clause."""
    text = (text.splitlines() or [""])[0].split(" (", 1)[0]
    return text if len(text) <= WARNING_CHARS else text[: WARNING_CHARS - 1].rstrip() + "…"


def _names_sensor(warning: Mapping, sensor: str) -> bool:
    """Whether a warning is about one sensor: its stage's (its consistency check's too), one of
    the validation or of a rule's log that names it (``mag: ...``, ``... magnetometer ...``), or
    a flag of the temperature hold-out on one of its axes."""
    source, text = str(warning.get("source", "")), str(warning["text"])
    name = SENSOR_TITLES[sensor].lower()
    if source.startswith(sensor):
        return True
    if source.startswith("temperature_holdout"):
        return f" {sensor} " in f" {text}"
    if source.startswith(("validation", "logs/")):
        return text.startswith(f"{sensor}:") or name in text.lower()
    return False


def headline(
    calibration: Mapping,
    results: Mapping[str, Mapping | None],
    validation: Mapping | None,
    warnings: Sequence[Mapping],
    undetermined: Mapping[str, Sequence[str]] | None = None,
) -> list[dict]:
    """Per sensor: what was calibrated and how, what was not determined or was fixed, the
    figures that say how well (held out against the reference where there is one, else the
    reference-free ones, with their basis), and the warnings that name it."""
    missing = dict(calibration.get("missing", {}))
    undetermined = undetermined or {}
    out = []
    for sensor in ("acc", "gyr", "mag"):
        own = [w["summary"] for w in merged_warnings(warnings) if _names_sensor(w, sensor)]
        if sensor in missing:
            first = str(missing[sensor]).split(": ", 1)[0]  # the sensor section has the rest
            out.append({"sensor": SENSOR_TITLES[sensor], "calibrated": False,
                        "what": f"not calibrated: {first}", "figures": [], "basis": "",
                        "warnings": own, "undetermined": [],
                        "anchor": SENSOR_TITLES[sensor].lower()})  # fmt: skip
            continue
        cal = calibration.get(sensor) or {}
        found = _held_out(sensor, validation) or _fallback(sensor, results.get(sensor))
        figures, basis = found if found else ([], "no check of this sensor ran")
        out.append({"sensor": SENSOR_TITLES[sensor], "calibrated": True,
                    "what": cal.get("method") or "method not stated", "figures": figures,
                    "basis": basis, "warnings": own,
                    "undetermined": list(undetermined.get(sensor, [])),
                    "anchor": SENSOR_TITLES[sensor].lower()})  # fmt: skip
    return out
