"""The lab report's section on the standard deviations checked against fits on independent
parts of the data, and the same rows as a Markdown table over many sessions.

Context of ``templates/_consistency.html.j2`` from ``results/{dataset}/consistency.json``
(:func:`imucal.validation.consistency.check_parts`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

#: The groups shown, in this order (``all``: bias and matrix together).
GROUPS = ("bias", "matrix", "scale", "xi_rad", "alpha_rad", "all")
#: Columns of a row, in the order of the tables.
COLUMNS = (
    "sensor", "stage", "scheme", *GROUPS, "largest |z|", "left out one at a time",
    "inflation (bias, matrix)", "held out / nominal",
)  # fmt: skip


def _number(value: float | None, digits: int = 2) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def consistency_rows(check: Mapping) -> list[dict]:
    """One row per sensor of a session's check: the RMS z of each group with its rank, the
    largest |z| and its parameter, the stage's leave-one-out RMS z, the inflation and the
    held-out error over the nominal calibration's (the stage's own poses left out, else each
    part under the other's calibration)."""
    rows = []
    for sensor, entry in check.get("sensors", {}).items():
        parts = entry.get("parts") or {}
        groups = parts.get("groups", {})
        loo = entry.get("leave_one_out")
        heldout = entry.get("own_heldout") or parts.get("heldout") or {}
        factors = entry["inflation"]
        row = {
            "sensor": sensor,
            "stage": entry["stage"],
            "scheme": parts.get("scheme") or f"not split: {entry.get('reason', '')}",
        }
        for group in GROUPS:
            g = groups.get(group)
            row[group] = (
                "-" if not g or g["rms_z"] is None else f"{_number(g['rms_z'])} ({g['rank']})"
            )
        worst = parts.get("max_abs_z")
        row["largest |z|"] = (
            "-" if worst is None else f"{_number(worst, 1)} ({parts['max_parameter']})"
        )
        row["left out one at a time"] = "-" if not loo else f"{_number(loo['rms_z'])} ({loo['n']})"
        row["inflation (bias, matrix)"] = (
            f"x{_number(factors['bias'])}, x{_number(factors['matrix'])}"
        )
        row["held out / nominal"] = _number(heldout.get("ratio"), 3)
        rows.append(row)
    return rows


def consistency_section(check: Mapping | None) -> dict | None:
    """Context of the report's section, None without a check."""
    if check is None:
        return None
    return {
        "rows": consistency_rows(check),
        "columns": COLUMNS,
        "limit": check.get("limit_rms_z"),
        "heldout_ratio": check.get("heldout_ratio"),
    }


def markdown_table(checks: Mapping[str, Mapping]) -> str:
    """The rows of many sessions' checks as one Markdown table (dataset first)."""
    header = [c.replace("|", "\\|") for c in ("dataset", *COLUMNS)]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for dataset, check in checks.items():
        for row in consistency_rows(check):
            cells = [f"`{dataset}`", *(str(row[c]).replace("|", "\\|") for c in COLUMNS)]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
