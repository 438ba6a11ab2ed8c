"""The CATS thermal comparison's table and sentences, written from the hold-out's JSON.

Run from the repository root after the workflow's hold-out (``snakemake --cores 2
results/spluque_cats_thermal/temperature_holdout.json``)::

    python tests/benchmarks/peers/thermal_tables.py

It rewrites the generated blocks (between ``<!-- generated: cats-thermal ... -->`` markers) of
docs/real-recordings.md (the table of every pose x sensor x axis cell, the flags, what ships)
and README.md (the figures and the flags in three sentences). Nothing in them is typed by
hand: every "better" or "worse" comes from an interval of the JSON.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Mapping
from pathlib import Path

from imucal.report.docblocks import replace_block

REPO = Path(__file__).resolve().parents[3]
HOLDOUT = REPO / "results" / "spluque_cats_thermal" / "temperature_holdout.json"
#: Display unit per sensor: (label, factor from SI).
UNITS = {"gyr": ("mdeg/s", 180.0 / math.pi * 1e3), "acc": ("mm/s^2", 1e3),
         "mag": ("1e-3 field norm", 1e3)}  # fmt: skip


def _ci(c: Mapping, name: str, digits: int = 3) -> str:
    lo, hi = c[f"{name}_ci95"]
    return f"{c[name]:.{digits}f} ({lo:.{digits}f}-{hi:.{digits}f})"


def peers_of(d: Mapping) -> list[str]:
    return [m for m in d["methods"] if m not in ("none", "term")]


def table(d: Mapping) -> str:
    """The Markdown table of every cell (and the pooled rows), the flags and what ships."""
    peers = peers_of(d)
    head = ["held out", "sensor", "axis", "order", "none", "term", *peers, "term / none (95 %)",
            *[f"term / {p} (95 %)" for p in peers], "term taken"]  # fmt: skip
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in d["summary"] + d["cells"]:
        factor = UNITS[c["sensor"]][1]
        order = c.get("order", ", ".join(map(str, c.get("orders", []))))
        rms = [f"{factor * c[f'rms_{m}']:.2f}" for m in ("none", "term", *peers)]
        versus = [_ci(c, f"term_vs_{p}", 4) for p in peers]
        taken = "yes" if c["taken"] else ("**no (flagged)**" if c["flags"] else "no")
        row = [c.get("held_out", "all three"), c["sensor"], c["axis"], str(order), *rms,
               _ci(c, "term_ratio"), *versus, taken]  # fmt: skip
        lines.append("| " + " | ".join(row) + " |")
    lines += ["", "Methods: " + "; ".join(f"`{m}` {label}" for m, label in d["methods"].items())
              + ". RMS of the 1 Hz held-out samples, " + ", ".join(
                  f"{s} in {u}" for s, (u, _) in UNITS.items()) + "; intervals with the fits' "
              "scatter (4-h blocks as clusters).", "", "Flagged cells (the term is not taken):", ""]  # fmt: skip
    flagged = [c for c in d["summary"] + d["cells"] if c["flags"]]
    lines += [f"- {c.get('held_out', 'all three poses')} {c['sensor']} {c['axis']}: "
              + "; ".join(c["flags"]) for c in flagged] or ["- none"]  # fmt: skip
    lines += ["", "What the hold-out takes, fitted on every pose (the session's "
              "`partial/calibration.json` carries it for the sensors the session calibrates; its "
              "`temperature_terms` names the rest):", ""]  # fmt: skip
    for e in d["shipped"]:
        if e["taken"]:
            coef = ", ".join(f"{v:.4g} ± {s:.2g}" for v, s in zip(e["coef"], e["coef_std"]))
            lines.append(f"- {e['sensor']} {e['axis']}: order {e['order']}, c = {coef} "
                         f"{e['unit']}/K^k about {e['reference_c']} deg C, valid "
                         f"{e['span_c'][0]:.1f}-{e['span_c'][1]:.1f} deg C")  # fmt: skip
        else:
            lines.append(f"- {e['sensor']} {e['axis']}: no term ({e['reason']})")
    return "\n".join(lines)


def sentences(d: Mapping) -> str:
    """The README's paragraph: pooled figures, where a method is resolvably ahead, the flags."""
    peers = peers_of(d)
    pooled = {(s["sensor"], s["axis"]): s for s in d["summary"]}

    def ratios(method: str, sensor: str) -> str:
        return " / ".join(f"{pooled[(sensor, a)][f'{method}_ratio']:.3f}" for a in "xyz")

    text = [
        "On a real thermal recording (a CATS tag in three static poses, settled samples over "
        f"{min(p['temp_span_c'][0] for p in d['poses']):.1f}-"
        f"{max(p['temp_span_c'][1] for p in d['poses']):.1f} deg C) each pose is held out in "
        "turn and predicted from the two others (rule `temperature_holdout`), with no term, "
        "the term, scikit-diveMove's `IMUcalibrate` (its line per pose, each fit pose's model "
        "alone) and PX4's per-axis cubic. Pooled over the held-out poses, the held-out RMS "
        "relative to no term on the accelerometer x / y / z, gyro x / y / z and magnetometer "
        f"x / y / z: term {ratios('term', 'acc')}, {ratios('term', 'gyr')}, "
        f"{ratios('term', 'mag')}; "
        + "; ".join(
            f"{p} {ratios(p, 'acc')}, {ratios(p, 'gyr')}, {ratios(p, 'mag')}" for p in peers
        )
        + "."  # fmt: skip
    ]
    cells = d["cells"] + d["summary"]
    ahead = [f"{c.get('held_out', 'all poses')} {c['sensor']} {c['axis']} (than {p}"
             + (", where the term is no term)" if c.get("order", 1) == 0 else ")")
             for c in cells for p in peers if c["verdicts"][p] == "better"]  # fmt: skip
    text.append(
        "Resolvably better than a peer (the interval of term / peer with the fits' scatter "
        f"below 1): {', '.join(ahead) if ahead else 'in no cell'}; elsewhere within their "
        "scatter or flagged."
    )
    flagged = [f"{c.get('held_out', 'all poses')} {c['sensor']} {c['axis']}" for c in cells
               if c["flags"]]  # fmt: skip
    shipped = [f"{e['sensor']} {e['axis']}" for e in d["shipped"] if e["taken"]]
    text.append(
        f"Flagged, the term not taken: {', '.join(flagged) if flagged else 'none'}. The term "
        f"ships where every held-out pose takes it: {', '.join(shipped) or 'nowhere'} (the "
        "session's `partial/calibration.json` carries those of its gyroscope; the table, the "
        "intervals and the reasons in `docs/real-recordings.md`, generated from the JSON)."
    )
    return " ".join(text)


def main() -> None:
    if not HOLDOUT.is_file():
        print(f"SKIPPED: {HOLDOUT.relative_to(REPO)} absent; run `snakemake --cores 2 "
              f"{HOLDOUT.relative_to(REPO)}` first")  # fmt: skip
        sys.exit(0)
    d = json.loads(HOLDOUT.read_text())
    replace_block(REPO / "docs" / "real-recordings.md", "cats-thermal", table(d))
    replace_block(REPO / "README.md", "cats-thermal", sentences(d))
    print(f"wrote the cats-thermal blocks of docs/real-recordings.md and README.md from "
          f"{HOLDOUT.relative_to(REPO)}")  # fmt: skip


if __name__ == "__main__":
    main()
