"""The sections of the lab report built from their artifacts: the session, each sensor's
parameters with their standard deviations, the paper's tables, the model terms, the gap
diagnosis and the noise.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from imucal.columns import AXES
from imucal.constants import REFERENCE
from imucal.modelterms import ModelTerms
from imucal.report.artifacts import load_json
from imucal.report.figures import embed_figure
from imucal.report.numbers import format_number, format_value
from imucal.terms.comparison import gap_comparison

#: Titles and units of the paper's tables in ``tables.csv`` (key: the ``table`` column).
TABLE_TITLES = {
    "I": ("Table I: gyroscope bias", "rad/s"),
    "II": ("Table II: gyroscope scale", "1"),
}


#: Units of the calibration parameters other than the bias (which is in the sensor's unit).
PARAMETER_UNITS = {"scale": "1", "xi_rad": "rad", "alpha_rad": "rad"}


PARAMETER_NAMES = {
    "bias": "bias o",
    "scale": "scale s",
    "xi_rad": "non-orthogonality ξ",
    "alpha_rad": "misalignment α",
}


#: Name of the rate-table recording (one of imucal.io.dataset.RECORDING_NAMES).
RATE_TABLE = "ratetable"


# Sentence shown when the ingest summary has no such recording.
RECORDING_ABSENT = {
    REFERENCE: "The dataset has no reference recording, so the calibrated module is not "
    "compared with a reference (no paper Fig. 20).",
    RATE_TABLE: "The dataset has no rate-table recording, so there are no rate-table "
    "magnitude errors (no paper Fig. 15); the gyroscope's method says how it was calibrated "
    "without one.",
}


#: A fixed parameter this close to 0 is printed as 0 (the rounding of a matrix decomposition).
FIXED_ZERO = 1e-12


def _with_std(value: Any, std: Any) -> str:
    """``value ± std`` (std with 2 significant digits), or the value alone if std is unknown."""
    if std is not None and float(std) == 0.0:
        shown = 0.0 if abs(float(value)) < FIXED_ZERO else value
        return f"{format_number(shown)} (fixed, not observable)"
    if std is None or not math.isfinite(float(std)):
        return format_number(value)
    return f"{format_number(value)} ± {format_number(std, 2)}"


def _shown_path(path: str | Path, folder: str | Path | None) -> str:
    """A raw file's path as the report shows it: relative to the dataset's folder."""
    if folder is None:
        return str(path)
    return Path(os.path.relpath(Path(path).resolve(), Path(folder).resolve())).as_posix()


def _name_parts(name: str) -> list[str]:
    """A file name cut after its separators (``_ - .``): the places a table may break it."""
    return [part for part in re.split(r"(?<=[_\-.])", name) if part]


def session_section(
    summary: Mapping, declared_reference: bool = False, folder: str | Path | None = None
) -> dict:
    recordings = summary.get("recordings", {})
    rows, gaps = [], []
    for name, rec in recordings.items():
        lost_fraction = rec.get("lost_fraction")
        rows.append(
            {
                "recording": name,
                "file": Path(rec["source"]).name if rec.get("source") else "n/a",
                "file_parts": _name_parts(Path(rec["source"]).name if rec.get("source") else "n/a"),
                "source": _shown_path(rec["source"], folder) if rec.get("source") else "n/a",
                "format": rec.get("format") or "n/a",
                "sha256": rec.get("sha256") or "n/a",
                "rows": format_number(rec.get("rows")),
                "duration_s": format_number(rec.get("duration_s")),
                "rate_hz": format_number(rec.get("rate_hz")),
                "received_rate_hz": format_number(rec.get("received_rate_hz")),
                "mag_rate_hz": format_number(rec.get("mag_rate_hz")),
                "lost_packets": format_number(rec.get("lost_packets")),
                "lost_pct": format_number(
                    None if lost_fraction is None else 100 * lost_fraction, 3
                ),
                "n_gaps": format_number(rec.get("n_gaps")),
                "duplicated_rows": format_number(rec.get("duplicated_rows")),
                "out_of_order_rows": format_number(rec.get("out_of_order_rows")),
                "flag": bool(
                    rec.get("lost_packets")
                    or rec.get("duplicated_rows")
                    or rec.get("out_of_order_rows")
                ),
            }
        )
        listed = rec.get("gaps") or []
        if listed:
            gaps.append(
                {
                    "recording": name,
                    "n_gaps": int(rec.get("n_gaps", len(listed))),
                    "n_listed": len(listed),
                    "rows": [
                        {
                            "line": format_number(g.get("line")),
                            "t_s": format_number(g.get("t_s"), 6),
                            "dt_s": format_number(g.get("dt_s"), 3),
                            "seq_before": format_number(g.get("seq_before")),
                            "seq": format_number(g.get("seq")),
                            "lost": format_number(g.get("lost")),
                        }
                        for g in listed
                    ],
                }
            )
    durations = [
        rec.get("duration_s") or 0.0 for name, rec in recordings.items() if name != REFERENCE
    ]
    absent = {name for name in RECORDING_ABSENT if name not in recordings}
    if declared_reference:
        absent.discard(REFERENCE)  # a reference declared with a recording (dataset.yaml)
    notes = [text for name, text in RECORDING_ABSENT.items() if name in absent]
    return {
        "recordings": rows,
        "gaps": gaps,
        "n_imu_recordings": len(durations),
        "imu_duration_s": format_number(sum(durations)),
        "total_lost_packets": format_number(
            summary.get(
                "lost_packets", sum(r.get("lost_packets") or 0 for r in recordings.values())
            )
        ),
        "notes": notes,
        "folder": None if folder is None else _folder_shown(folder),
    }


def _folder_shown(folder: str | Path) -> str:
    """The dataset's folder: relative to the working directory when inside it."""
    try:
        return Path(folder).resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return str(folder)


def sensor_parameters(sensor: str, cal: Mapping) -> dict:
    """Parameter rows (x, y, z with ± std) and the matrix of one sensor of calibration.json."""
    std = cal.get("std") or {}
    unit = cal.get("unit_in", "")
    rows = []
    for key in ("bias", "scale", "xi_rad", "alpha_rad"):
        if key not in cal:
            continue
        unit_of = unit if key == "bias" else PARAMETER_UNITS[key]
        sd = std.get(key)
        rows.append(
            {
                "name": PARAMETER_NAMES[key],
                "unit": unit_of,
                "cells": [
                    _with_std(v, None if sd is None else sd[i]) for i, v in enumerate(cal[key])
                ],
            }
        )
    sd_matrix = std.get("matrix")
    matrix = [
        [_with_std(v, None if sd_matrix is None else sd_matrix[i][j]) for j, v in enumerate(row)]
        for i, row in enumerate(cal["matrix"])
    ]
    unknown_std = [
        PARAMETER_NAMES.get(k, k)
        for k in ("bias", "matrix", "scale", "xi_rad", "alpha_rad")
        if k not in std
    ]
    return {
        "sensor": sensor,
        "unit_in": unit,
        "unit_out": cal.get("unit_out", unit),
        "method": cal.get("method") or "not stated",
        "rows": rows,
        "matrix": matrix,
        "std_unknown": unknown_std,
        "quality": _quality_rows(cal.get("quality") or {}),
        "has_covariance": cal.get("covariance") is not None,
    }


def undetermined_parameters(sensor: str, cal: Mapping, recordings: Collection[str]) -> list[str]:
    """What one sensor's calibration did not determine: parameters fixed (standard deviation
    0) and parameters with no standard deviation, each with the reason where it is known."""
    std = cal.get("std") or {}
    why = (
        "not observable without a rate table"
        if sensor == "gyr" and RATE_TABLE not in recordings
        else "not observable from these recordings"
    )
    out = []
    for key in ("bias", "scale", "xi_rad", "alpha_rad"):
        if key not in cal:
            continue
        sd = std.get(key)
        if sd is None:
            out.append(f"{PARAMETER_NAMES[key]}: no standard deviation known")
            continue
        fixed = [a for a, v in zip(AXES, sd, strict=True) if v is not None and float(v) == 0.0]
        if fixed:
            values = {float(cal[key][AXES.index(a)]) for a in fixed}
            at = format_number(0.0 if all(abs(v) < FIXED_ZERO for v in values) else min(values))
            axes = "" if len(fixed) == 3 else f" ({', '.join(fixed)})"
            out.append(f"{PARAMETER_NAMES[key]}{axes}: fixed at {at}, {why}")
    if "matrix" in cal and "matrix" not in std:
        out.append("calibration matrix: no standard deviation known")
    return out


def _quality_rows(quality: Mapping) -> list[dict]:
    """Per stage behind a calibration: chi-square / dof, inflation and the rule stated."""
    rows = []
    for stage, q in quality.items():
        ratio = q.get("chi2_per_dof")
        inflation = q.get("inflation")
        rows.append(
            {
                "stage": stage,
                "chi2": "" if ratio is None else f"{format_number(q['chi2'], 3)} / {q['dof']}",
                "ratio": "" if ratio is None else format_number(ratio, 3),
                "inflated": (
                    ""
                    if inflation is None
                    else (
                        f"yes: covariance x {format_number(inflation, 3)}"
                        if inflation > 1
                        else "no"
                    )
                ),
                "rule": q.get("rule", ""),
                "crlb": (
                    "" if q.get("std_over_crlb") is None else format_number(q["std_over_crlb"], 3)
                ),
            }
        )
    return rows


def paper_tables(tables: pd.DataFrame | None) -> list[dict]:
    if tables is None:
        return []
    missing = {"table", "row", *AXES} - set(tables.columns)
    if missing:
        raise ValueError(
            f"tables.csv has columns {list(tables.columns)}; expected table, row, x, y, z "
            f"(missing {sorted(missing)})"
        )
    out = []
    for name, group in tables.groupby("table", sort=False):
        key = re.sub(r"^table\s+", "", str(name), flags=re.IGNORECASE)
        title, unit = TABLE_TITLES.get(key, (f"Table {key}", None))
        if "unit" in group.columns and group["unit"].notna().any():
            unit = str(group["unit"].dropna().iloc[0])
        rows = [
            {"row": str(r["row"]), "cells": [format_number(r[a]) for a in AXES]}
            for _, r in group.iterrows()
        ]
        has_truth = any(r["row"].strip().lower() == "truth" for r in rows)
        out.append({"title": title, "unit": unit, "rows": rows, "has_truth": has_truth})
    return out


def _plus_minus(value: Any, std: Any) -> str:
    """``value ± std`` for scalars, vectors and matrices alike."""
    return f"{format_value(value)} ± {format_value(std, 2)}"


def _heldout_row(term: str, h: Mapping) -> dict:
    """One row of the held-out table from a comparison of :mod:`imucal.terms.heldout`."""
    if "note" in h:
        return {"term": term, "residual": h["note"], "rms": "", "achieved": "", "predicted": "",
                "verdict": ""}  # fmt: skip
    predicted = h["predicted_shrink"]
    verdict = ("no prediction" if predicted is None else
               "short of the prediction" if h["short_of_prediction"] else "as predicted or better")  # fmt: skip
    return {
        "term": term,
        "residual": h["residual"],
        "rms": f"{format_number(h['rms_without'], 3)} → {format_number(h['rms_with'], 3)}",
        "achieved": _plus_minus(h["achieved_shrink"], h["achieved_std"]),
        "predicted": format_number(predicted, 2) if predicted is not None else "-",
        "verdict": verdict,
    }


def terms_section(
    paths: Sequence[str | Path] | None, gap: Sequence[str | Path] | None
) -> dict | None:
    """Context of the model-terms partial (``_terms.html.j2``) from terms.json and
    gap/after.json (in that order), with the gap before from diagnosis.json."""
    if not paths:
        return None
    terms_path, after_path = paths
    summary = load_json(terms_path, "model terms")
    after = load_json(after_path, "diagnosis after the model terms")
    before = load_json(gap[0], "gap diagnosis") if gap else {}
    rows = [
        {
            "term": name,
            "setting": r["setting"],
            "included": "in the model" if name in summary["in_model"] else "not in the model",
            "reason": r["reason"],
        }
        for name, r in summary["terms"].items()
    ]
    model = ModelTerms.from_dict((summary.get("calibration") or {}).get("terms", {}))
    values = [{"term": row.name, "value": _plus_minus(row.value, row.std), "unit": row.unit}
              for term in model.values() for row in term.report_rows()]  # fmt: skip
    heldout = [_heldout_row(name, r["heldout"]) for name, r in summary["terms"].items()
               if r.get("heldout")]  # fmt: skip
    p2p = summary.get("heldout_pose_to_pose")
    if p2p and "note" not in p2p:
        heldout.append(_heldout_row("all terms in the model", p2p))
    gap_before = (before.get("gap") or {}).get("total")
    gap_after = (after.get("gap") or {}).get("total")
    compared = gap_comparison(before, after, summary["in_model"])
    return {
        "gap_compared": (
            {
                k: (v if k in ("verdict", "still_explained") else format_number(v))
                for k, v in compared.items()
            }  # fmt: skip
            if compared
            else None
        ),
        "rows": rows,
        "coefficients": values,
        "heldout": heldout,
        "in_model": summary["in_model"],
        "gap_before": format_number(gap_before),
        "gap_after": format_number(gap_after) if gap_after is not None else None,
        "remaining_after": format_number((after.get("remaining") or {}).get("total")),
        "explained_after": list(after.get("explained", [])),
        "note": after.get("note", ""),
    }


#: The IEEE 952 noise terms' names.
NOISE_TERMS = {
    "Q": "Q, quantisation",
    "N": "N, white noise (density)",
    "B": "B, bias instability",
    "K": "K, rate random walk",
    "R": "R, rate ramp",
}


def _pretty_unit(unit: str) -> str:
    """A unit as the report prints it: ``(m/s^2)/sqrt(Hz)`` as ``(m/s²)/√Hz``."""
    return unit.replace("^2", "²").replace("sqrt(Hz)", "√Hz").replace("sqrt(s)", "√s")


def noise_section(paths: Sequence[str | Path] | None) -> dict | None:
    """Context of the noise partial (``_noise.html.j2``): noise.json, then its figure."""
    if not paths:
        return None
    from imucal.pipeline.outcome import not_run_reason

    path, *figures = [Path(p) for p in paths]
    d = load_json(path, "noise")
    reason = not_run_reason(d)
    if reason:
        return {"reason": reason, "rows": [], "figure": None}
    tables = []
    for sensor, data in d["sensors"].items():
        rows = []
        for axis, fit in data["axes"].items():
            cells = {}
            for term, t in fit["terms"].items():
                if t["resolved"]:
                    cells[term] = f"{format_number(t['value'], 3)} ± {format_number(t['std'], 2)}"
                else:
                    cells[term] = f"< {format_number(t['upper_bound'], 3)}"
            rows.append(
                {"axis": axis, "cells": cells, "chi2": format_number(fit["reduced_chi2"], 2)}
            )
        first = next(iter(data["axes"].values()))["terms"]
        headers = [{"term": t, "name": NOISE_TERMS.get(t, t), "unit": _pretty_unit(first[t]["unit"])}
                   for t in d["terms"]]  # fmt: skip
        title = {"acc": "Accelerometer", "gyr": "Gyroscope", "mag": "Magnetometer"}.get(sensor)
        tables.append({"sensor": sensor, "title": title or sensor, "headers": headers,
                       "rows": rows})  # fmt: skip
    return {
        "reason": None,
        "recording": d["recording"],
        "duration_s": format_number(d["duration_s"], 4),
        "rate_hz": format_number(d["rate_hz"], 4),
        "level": format_number(d["level"], 3),
        "terms": d["terms"],
        "tables": tables,
        "skipped": d.get("skipped", {}),
        "figure": embed_figure(figures[0]) if figures else None,
    }
