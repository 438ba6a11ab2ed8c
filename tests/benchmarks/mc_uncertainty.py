"""Monte-Carlo check of the reported uncertainty: z = (estimate - truth) / reported std.

Each session draws a truth of the simulator's ``random`` preset, renders the paper's whole
protocol (:func:`imucal.sim.simulate_session`) and calibrates it in process. Protocol ``full``
runs the paper's chain (:func:`imucal.pipeline.full.calibrate_session`) twice: with the rate
table (path ``full``: acc, gyr from the table, mag) and without it (path ``tool_free``: the
gyroscope from eqs. 34-36). A partial protocol (:data:`PARTIAL`) keeps some of the session's
recordings, as a partial session would have them, and runs the partial path
(:func:`imucal.pipeline.partial.run_stages`); its path is the stage that gives the sensor's
final calibration. Per sensor, path and parameter it records the estimate, the truth and the
standard deviation of ``calibration.json``.

The tool-free gyroscope cannot observe ``T_N`` (eq. 36 fits ``T_R diag(s)``): its sessions set
the gyroscope's non-orthogonality of the truth to zero, the path's own assumption, so that its
scale and alpha are tested where the path's model holds (with xi != 0 they carry a model error
of the size of xi, which no noise covariance describes).

Usage::

    python tests/benchmarks/mc_uncertainty.py run --first 0 --count 20 --out chunk.json \\
        [--protocol full|ferraris|poses|ratetable|static|tumble|platform] \\
        [--effects temperature_drift,bias_instability,placement_error]
    python tests/benchmarks/mc_uncertainty.py table chunk*.json --out table.md

``run`` writes one JSON record per session and sensor; ``table`` prints RMS z and the coverage of
the 95 % intervals (|z| < 1.96) per sensor, path and parameter group. The Snakemake targets
``uncertainty_benchmark`` and ``uncertainty_partial`` (workflow/rules/benchmark.smk) run both.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from imucal import errormodel
from imucal.calibration import SensorCalibration
from imucal.columns import AXES
from imucal.pipeline import partial
from imucal.pipeline.full import PipelineOptions, calibrate_session
from imucal.segments.segmentation import segment_dataset
from imucal.sim import make_effect, make_truth, simulate_session
from imucal.sim.effects import stream_rng
from imucal.sim.protocol import CUBE_UP_B
from imucal.uncertainty import GROUPS, PARAMETERS

RANGE_COUNTS = {"acc": 32767, "gyr": 32767, "mag": 32767}
#: Parameter groups of the table (the matrix entries are summarised by these).
TABLE_GROUPS = ("bias", "scale", "xi_rad", "alpha_rad", "matrix")
Z95 = 1.959963984540054


@dataclasses.dataclass(frozen=True)
class PartialProtocol:
    """A partial session cut from a simulated one: what it keeps and what is checked.

    Attributes
    ----------
    recordings : dict
        Recording name of the partial session -> simulated recording it takes (its samples
        and its segments).
    final : dict
        Sensor -> the stage that must give its final calibration (the record's path).
    frame : dict
        Sensor -> frame of that calibration: 'B' (the platform's frame), 'upper' (the sensor's
        own frame: the truth's upper-triangular factor, ``matrix = Q U``, no ``T_R``) or
        'acc upper' (the frame of the accelerometer's upper-triangular factor,
        ``Q_acc^T matrix``).
    gyro_xi_zero : bool
        The truth's gyroscope non-orthogonality set to zero, the tool-free path's own
        assumption (as for the path ``tool_free`` of the whole protocol).
    """

    recordings: dict
    final: dict
    frame: dict
    gyro_xi_zero: bool = False


#: The partial protocols: Ferraris' six faces (the cube's first six positions, their up
#: direction known) with known-angle turns (the rotation3d phases, 720 deg each); hand-placed
#: poses with a static recording; the rate table alone; a static recording alone; a tumble
#: (the rotation3d recording without its phases) for the magnetometer; the platform without
#: cube and rate table (the tool-free gyroscope and the magnetometer's two steps).
PARTIAL = {
    "ferraris": PartialProtocol(
        {"ferraris": "cube", "rotation3d": "rotation3d", "static": "static"},
        {"acc": "acc_known_orientation", "gyr": "gyr_known_rotation"},
        {"acc": "B", "gyr": "B"},
    ),
    "poses": PartialProtocol(
        {"poses": "cube", "static": "static"},
        {"acc": "acc_cube", "gyr": "gyr_pose_to_pose"},
        {"acc": "upper", "gyr": "acc upper"},
    ),
    "ratetable": PartialProtocol(
        {"ratetable": "ratetable"}, {"gyr": "gyr_table"}, {"gyr": "upper"}
    ),
    "static": PartialProtocol({"static": "static"}, {"gyr": "gyr_bias"}, {"gyr": "B"}),
    "tumble": PartialProtocol({"tumble": "rotation3d"}, {"mag": "mag_step1"}, {"mag": "upper"}),
    "platform": PartialProtocol(
        {"rotation3d": "rotation3d", "static": "static"},
        {"gyr": "gyr_scale", "mag": "mag_step2"},
        {"gyr": "B", "mag": "B"},
        gyro_xi_zero=True,
    ),
}
PROTOCOLS = ("full", *PARTIAL)


def _parameters(cal: SensorCalibration) -> np.ndarray:
    d = cal.decomposition
    return np.concatenate([cal.bias, cal.matrix.ravel(), d.scale, d.xi_rad, d.alpha_rad])


def _reported_std(cal: SensorCalibration) -> np.ndarray:
    """Std of each of :data:`PARAMETERS`, shape (21,); 0 where the calibration reports none."""
    if cal.covariance is not None:
        return np.sqrt(np.clip(np.diag(cal.covariance), 0, None))
    std = np.zeros(len(PARAMETERS))
    for group, where in GROUPS.items():
        if group in cal.std:
            std[where] = np.ravel(cal.std[group])
    return std


def _without_gyro_xi(truth):
    gyr = truth.calibration.gyr
    d = gyr.decomposition
    matrix = errormodel.compose(d.scale, np.zeros(3), d.alpha_rad)
    cal = dataclasses.replace(truth.calibration, gyr=dataclasses.replace(gyr, matrix=matrix))
    return dataclasses.replace(truth, calibration=cal)


def _record(seed: int, path: str, est: SensorCalibration, truth: SensorCalibration) -> dict:
    return {
        "seed": seed,
        "path": path,
        "sensor": est.sensor,
        "estimate": _parameters(est).tolist(),
        "truth": _parameters(truth).tolist(),
        "std": _reported_std(est).tolist(),
    }


def _options(session) -> PipelineOptions:
    config = session.config
    return PipelineOptions(
        session.truth.world.gravity_m_s2,
        session.sensitivity,
        RANGE_COUNTS,
        {"axes": list(config.ratetable_axes), "rates_dps": list(config.rates_dps)},
    )


def run_full(seed: int, effects: tuple[str, ...]) -> list[dict]:
    """Simulate one session and return its records for the paths ``full`` and ``tool_free``."""
    records = []
    for path in ("full", "tool_free"):
        truth = make_truth("random", stream_rng(seed, "truth"))
        if path == "tool_free":
            truth = _without_gyro_xi(truth)
        session = simulate_session(truth, seed, effects=tuple(make_effect(e) for e in effects))
        imu = {rec: session.si_frame(rec) for rec in session.logs}
        options = _options(session)
        if path == "tool_free":
            imu.pop("ratetable")
            options = dataclasses.replace(options, ratetable=None)
        fit = calibrate_session(imu, None, options)
        for sensor in ("acc", "gyr", "mag") if path == "full" else ("gyr",):
            est = fit.calibration.sensor(sensor)
            records.append(_record(seed, path, est, session.truth.calibration.sensor(sensor)))
    return records


def _truth_in_frame(truth_cal, sensor: str, frame: str) -> SensorCalibration:
    """The true calibration of ``sensor`` in the frame a partial path calibrates it to."""
    cal = truth_cal.sensor(sensor)
    if frame == "B":
        return cal
    if frame == "upper":
        return dataclasses.replace(cal, matrix=errormodel.upper_triangular_factor(cal.matrix)[1])
    if frame == "acc upper":
        q_acc, _ = errormodel.upper_triangular_factor(truth_cal.acc.matrix)
        return dataclasses.replace(cal, matrix=q_acc.T @ cal.matrix)
    raise ValueError(f"frame {frame!r}: expected 'B', 'upper' or 'acc upper'")


def partial_session(
    protocol: PartialProtocol, tables: dict[str, pd.DataFrame], segments: pd.DataFrame
) -> tuple[dict[str, pd.DataFrame], pd.DataFrame]:
    """The tables and segments of a partial session cut from a whole one.

    Parameters
    ----------
    protocol : PartialProtocol
    tables : dict of str to DataFrame
        The whole session's recordings (SI units).
    segments : DataFrame
        Their segments table.

    Returns
    -------
    tables : dict of str to DataFrame
        The recordings the protocol keeps, under their partial names.
    segments : DataFrame
        Their segments under the partial names; the ferraris positions carry their ``up``
        direction (the cube's six faces; the V-block positions none) and the rotation3d phases
        of the ferraris protocol their ``angle_deg``.
    """
    kept = []
    for name, source in protocol.recordings.items():
        rows = segments[segments["recording"] == source].copy()
        if name == "tumble":  # a tumble has no phases: the alignment cannot run
            rows = rows.iloc[0:0]
        rows["recording"] = name
        if name == "ferraris":
            positions = rows["kind"] == "position"
            faces = ["+-"[int(sum(u) < 0)] + AXES[int(np.argmax(np.abs(u)))] for u in CUBE_UP_B]
            ups = [f if np.count_nonzero(u) == 1 else "" for f, u in zip(faces, CUBE_UP_B)]
            if positions.sum() != len(ups):
                raise ValueError(
                    f"ferraris: the segmentation found {int(positions.sum())} cube positions, "
                    f"expected {len(ups)} (the faces' up directions follow their order)"
                )
            rows["up"] = rows["up"].astype(object)
            rows.loc[positions, "up"] = ups
        if "ferraris" in protocol.recordings and name == "rotation3d":
            phases = rows["kind"] == "phase"
            rows.loc[phases, "angle_deg"] = 360.0 * rows.loc[phases, "turns"].astype(float)
        kept.append(rows)
    return (
        {name: tables[source] for name, source in protocol.recordings.items()},
        pd.concat(kept, ignore_index=True),
    )


def run_partial(seed: int, protocol: str, effects: tuple[str, ...]) -> list[dict]:
    """Simulate one session, calibrate the partial session of ``protocol`` cut from it.

    Raises
    ------
    ValueError
        When a checked sensor's final calibration comes from another stage than the protocol's
        (the partial path refused the stage on these data; its reason is in the message).
    """
    chosen = PARTIAL[protocol]
    truth = make_truth("random", stream_rng(seed, "truth"))
    if chosen.gyro_xi_zero:
        truth = _without_gyro_xi(truth)
    session = simulate_session(truth, seed, effects=tuple(make_effect(e) for e in effects))
    imu = {rec: session.si_frame(rec) for rec in session.logs}
    options = _options(session)
    segments = segment_dataset(imu, ratetable=dict(options.ratetable), fallback=True)
    tables, segments = partial_session(chosen, imu, segments)
    # the partial path's options: the session's gravity, rate table and ranges, every other
    # setting the schema's default
    ranges = {"acc": options.limit("acc"), "gyr": options.limit("gyr")}
    ranges = {sensor: value for sensor, value in ranges.items() if value is not None}
    options = PipelineOptions(options.gravity_m_s2, {}, {}, options.ratetable, ranges=ranges)
    outcomes = partial.run_stages(partial.Session(tables, segments, options))
    final = partial.final_calibration(outcomes, options)
    reasons = {o.name: o.reason for o in outcomes}
    records = []
    for sensor, stage in chosen.final.items():
        got = final["sensors"].get(sensor, {}).get("stage")
        if got != stage:
            raise ValueError(
                f"{protocol}: the {sensor} calibration came from {got!r}, not {stage!r} "
                f"({stage}: {reasons[stage]})"
            )
        est = SensorCalibration.from_dict(sensor, final["sensors"][sensor]["calibration"])
        true = _truth_in_frame(session.truth.calibration, sensor, chosen.frame[sensor])
        records.append(_record(seed, stage, est, true))
    return records


def run_session(seed: int, protocol: str, effects: tuple[str, ...]) -> list[dict]:
    """The records of one simulated session under ``protocol`` (one of :data:`PROTOCOLS`)."""
    if protocol == "full":
        return run_full(seed, effects)
    if protocol not in PARTIAL:
        raise ValueError(f"protocol {protocol!r}: expected one of {PROTOCOLS}")
    return run_partial(seed, protocol, effects)


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
    run.add_argument("--protocol", choices=PROTOCOLS, default="full", help="see PARTIAL")
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
                records += run_session(seed, args.protocol, effects)
            except ValueError as err:  # a session the chain refuses is counted, not hidden
                failed.append({"seed": seed, "error": str(err)})
        Path(args.out).write_text(
            json.dumps(
                {
                    "protocol": args.protocol,
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
    effects = sorted({e for c in chunks for e in c["effects"]}) or ["none"]
    text = ""
    for protocol in dict.fromkeys(c["protocol"] for c in chunks):
        mine = [c for c in chunks if c["protocol"] == protocol]
        sessions = len({r["seed"] for c in mine for r in c["records"]})
        failed = [f for c in mine for f in c["failed"]]
        text += (
            f"Sessions, protocol {protocol}: {sessions} calibrated, {len(failed)} refused by "
            f"the chain.\n"
        )
        for f in failed:
            text += f"Refused: {protocol} seed {f['seed']}: {f['error']}\n"
    text += f"Effects: {', '.join(effects)}.\n\n" + table(records)
    Path(args.out).write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
