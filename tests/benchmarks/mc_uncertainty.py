"""Monte-Carlo check of the reported uncertainty: z = (estimate - truth) / reported std.

Each session draws a truth of the simulator's ``random`` preset, renders the paper's whole
protocol (:func:`imucal.sim.simulate_session`) and calibrates it in process
(:func:`imucal.pipeline.full.calibrate_session`) twice: with the rate table (path ``full``:
acc, gyr from the table, mag) and without it (path ``tool_free``: the gyroscope from eqs.
34-36). Per sensor, path and parameter it records the estimate, the truth and the standard
deviation of ``calibration.json``.

The tool-free gyroscope cannot observe ``T_N`` (eq. 36 fits ``T_R diag(s)``): its sessions set
the gyroscope's non-orthogonality of the truth to zero, the path's own assumption, so that its
scale and alpha are tested where the path's model holds (with xi != 0 they carry a model error
of the size of xi, which no noise covariance describes).

Usage::

    python tests/benchmarks/mc_uncertainty.py run --first 0 --count 20 --out chunk.json \\
        [--effects temperature_drift,bias_instability,placement_error]
    python tests/benchmarks/mc_uncertainty.py table chunk*.json --out table.md

``run`` writes one JSON record per session; ``table`` prints RMS z and the coverage of the
95 % intervals (|z| < 1.96) per sensor, path and parameter group. The Snakemake target
``uncertainty_benchmark`` (workflow/rules/benchmark.smk) runs both.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from imucal import errormodel
from imucal.calibration import ImuCalibration, SensorCalibration
from imucal.pipeline.full import PipelineOptions, calibrate_session
from imucal.sim import make_effect, make_truth, simulate_session
from imucal.sim.effects import stream_rng
from imucal.uncertainty import GROUPS, PARAMETERS

RANGE_COUNTS = {"acc": 32767, "gyr": 32767, "mag": 32767}
#: Parameter groups of the table (the matrix entries are summarised by these).
TABLE_GROUPS = ("bias", "scale", "xi_rad", "alpha_rad", "matrix")
Z95 = 1.959963984540054


def _parameters(cal: SensorCalibration) -> np.ndarray:
    d = cal.decomposition
    return np.concatenate([cal.bias, cal.matrix.ravel(), d.scale, d.xi_rad, d.alpha_rad])


def _without_gyro_xi(truth):
    gyr = truth.calibration.gyr
    d = gyr.decomposition
    matrix = errormodel.compose(d.scale, np.zeros(3), d.alpha_rad)
    cal = dataclasses.replace(truth.calibration, gyr=dataclasses.replace(gyr, matrix=matrix))
    return dataclasses.replace(truth, calibration=cal)


def _records(seed: int, path: str, fit_cal: ImuCalibration, truth_cal, sensors) -> list[dict]:
    out = []
    for sensor in sensors:
        est = fit_cal.sensor(sensor)
        true = _parameters(truth_cal.sensor(sensor))
        value = _parameters(est)
        std = np.sqrt(np.clip(np.diag(est.covariance), 0, None))
        out.append(
            {
                "seed": seed,
                "path": path,
                "sensor": sensor,
                "estimate": value.tolist(),
                "truth": true.tolist(),
                "std": std.tolist(),
            }
        )
    return out


def run_session(seed: int, effects: tuple[str, ...]) -> list[dict]:
    """Simulate one session and return its records for both paths."""
    records = []
    for path in ("full", "tool_free"):
        truth = make_truth("random", stream_rng(seed, "truth"))
        if path == "tool_free":
            truth = _without_gyro_xi(truth)
        session = simulate_session(truth, seed, effects=tuple(make_effect(e) for e in effects))
        imu = {rec: session.si_frame(rec) for rec in session.logs}
        config = session.config
        options = PipelineOptions(
            session.truth.world.gravity_m_s2,
            session.sensitivity,
            RANGE_COUNTS,
            {"axes": list(config.ratetable_axes), "rates_dps": list(config.rates_dps)},
        )
        if path == "tool_free":
            imu.pop("ratetable")
            options = dataclasses.replace(options, ratetable=None)
        fit = calibrate_session(imu, None, options)
        sensors = ("acc", "gyr", "mag") if path == "full" else ("gyr",)
        records += _records(seed, path, fit.calibration, session.truth.calibration, sensors)
    return records


def table(records: list[dict]) -> str:
    """Markdown table: RMS z and 95 % coverage per path, sensor and parameter group."""
    rows = [
        "| path | sensor | group | n | RMS z | 95 % coverage | not in [0.85, 1.2] or [92, 98] % |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    keys = sorted({(r["path"], r["sensor"]) for r in records})
    for path, sensor in keys:
        chosen = [r for r in records if r["path"] == path and r["sensor"] == sensor]
        est = np.array([r["estimate"] for r in chosen])
        truth = np.array([r["truth"] for r in chosen])
        std = np.array([r["std"] for r in chosen])
        for group in TABLE_GROUPS:
            s = GROUPS[group]
            sd = std[:, s]
            known = sd > 0
            if not known.any():
                rows.append(f"| {path} | {sensor} | {group} | 0 | - | - | not estimated |")
                continue
            z = ((est[:, s] - truth[:, s])[known]) / sd[known]
            rms = float(np.sqrt(np.mean(z**2)))
            cover = float(np.mean(np.abs(z) < Z95) * 100)
            flag = "" if 0.85 <= rms <= 1.2 and 92 <= cover <= 98 else "outside"
            rows.append(
                f"| {path} | {sensor} | {group} | {z.size} | {rms:.2f} | {cover:.1f} | {flag} |"
            )
    return "\n".join(rows) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run")
    run.add_argument("--first", type=int, required=True, help="first session seed")
    run.add_argument("--count", type=int, required=True, help="number of sessions")
    run.add_argument("--effects", default="", help="comma-separated simulator effects")
    run.add_argument("--out", required=True)
    tab = sub.add_parser("table")
    tab.add_argument("inputs", nargs="+")
    tab.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    if args.command == "run":
        effects = tuple(e for e in args.effects.split(",") if e)
        records, failed = [], []
        start = time.time()
        for seed in range(args.first, args.first + args.count):
            try:
                records += run_session(seed, effects)
            except ValueError as err:  # a session the chain refuses is counted, not hidden
                failed.append({"seed": seed, "error": str(err)})
        Path(args.out).write_text(
            json.dumps(
                {
                    "effects": list(effects),
                    "parameters": list(PARAMETERS),
                    "records": records,
                    "failed": failed,
                    "seconds": time.time() - start,
                }
            )
        )
        return 0
    chunks = [json.loads(Path(p).read_text()) for p in args.inputs]
    records = [r for c in chunks for r in c["records"]]
    failed = [f for c in chunks for f in c["failed"]]
    sessions = len({r["seed"] for r in records})
    effects = sorted({e for c in chunks for e in c["effects"]}) or ["none"]
    text = (
        f"Sessions: {sessions} calibrated, {len(failed)} refused by the chain; "
        f"effects: {', '.join(effects)}.\n\n" + table(records)
    )
    for f in failed:
        text += f"\nRefused: seed {f['seed']}: {f['error']}"
    Path(args.out).write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
