"""Render a simulated fleet: N sensor units, S sessions each, and its sample sheet.

    python tests/benchmarks/fleet/make_fleet.py OUT [--units 20] [--sessions 3] [--static-s 60]
    snakemake --cores 2 fleet --config fleet='{"sessions": "OUT/sessions.tsv"}'

Each unit has its own truth (the simulator's ``random`` preset, seeded by the unit) shared by its
sessions, which differ in noise and protocol timing and are 60 days apart. Two units are made to
stand out, so that the fleet report has something true to find: unit ``U03``'s accelerometer is
20 % less sensitive on x than it should be (a damaged part: an outlier across units), and unit
``U07``'s gyroscope bias on x grows by 0.01 rad/s (0.57 deg/s) from one session to the next (an
ageing part: drift between calibrations). ``OUT/fleet_truth.json`` says so.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd

from imucal.sim.effects import stream_rng
from imucal.sim.protocol import ProtocolConfig
from imucal.sim.session import preset_effects, simulate_session, write_session
from imucal.sim.truth import make_truth

OUTLIER, DRIFTING = "U03", "U07"
START = pd.Timestamp("2026-01-05")


def unit_truth(serial: str, unit: int, session: int):
    """The truth of one session of a unit (with the two made-up faults)."""
    truth = make_truth("random", stream_rng(100 + unit, "truth"))
    cal = truth.calibration
    if serial == OUTLIER:
        matrix = cal.acc.matrix.copy()
        matrix[:, 0] /= 0.8  # readings on x 20 % low: the calibration scales them back up
        cal = dataclasses.replace(cal, acc=dataclasses.replace(cal.acc, matrix=matrix))
    if serial == DRIFTING:
        bias = cal.gyr.bias + np.array([0.01 * session, 0.0, 0.0])
        cal = dataclasses.replace(cal, gyr=dataclasses.replace(cal.gyr, bias=bias))
    return dataclasses.replace(truth, calibration=cal)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("--units", type=int, default=20)
    parser.add_argument("--sessions", type=int, default=3)
    parser.add_argument("--static-s", type=float, default=60.0)
    args = parser.parse_args()
    out = Path(args.out)
    rows = []
    for unit in range(1, args.units + 1):
        serial = f"U{unit:02d}"
        for session in range(args.sessions):
            name = f"{serial.lower()}_s{session + 1}"
            truth = unit_truth(serial, unit, session)
            rendered = simulate_session(
                truth, 1000 * unit + session, ProtocolConfig(static_s=args.static_s),
                preset_effects("random"), name=name,
            )  # fmt: skip
            write_session(rendered, out / name)
            day = START + pd.Timedelta(days=60 * session + unit)
            rows.append((name, name, serial, day.strftime("%Y-%m-%d"), "simulator"))
            print(f"wrote {out / name}")
    sheet = pd.DataFrame(rows, columns=["dataset", "path", "serial", "date", "operator"])
    sheet.to_csv(out / "sessions.tsv", sep="\t", index=False)
    faults = {
        OUTLIER: "acc scale x 20 % low in every session (outlier across units)",
        DRIFTING: "gyro bias x +0.01 rad/s per session (drift between calibrations)",
    }
    (out / "fleet_truth.json").write_text(json.dumps(faults, indent=2) + "\n")
    print(f"wrote {out / 'sessions.tsv'}: {len(sheet)} sessions of {args.units} units")


if __name__ == "__main__":
    main()
