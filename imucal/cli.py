"""The ``imucal`` command: subcommands ``simulate``, ``apply``, ``export`` and ``lookup``."""

from __future__ import annotations

import argparse
import sys

from imucal.sim import EFFECTS, PRESETS, parse_effect, simulate
from imucal.sim.effects import REALISTIC


def _effect(spec: str):
    try:
        return parse_effect(spec)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _effects_epilog() -> str:
    lines = ["effects and their defaults (a typical realistic magnitude; see docs/simulator.md):"]
    for name in REALISTIC:
        params = ",".join(f"{k}={v}" for k, v in REALISTIC[name].items())
        lines.append(f"  {name}:{params}")
    return "\n".join(lines)


def _add_simulate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="render a simulated calibration session as a dataset folder",
        description=(
            "Render a complete calibration session (rotation3d, cube, ratetable, static, "
            "reference, truth.json) from a known truth; the same seed gives identical files."
        ),
        epilog=_effects_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("out_dir", help="dataset folder to write (created if needed)")
    p.add_argument("--preset", choices=PRESETS, default="paper", help="truth preset")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--effect",
        type=_effect,
        action="append",
        default=[],
        metavar="NAME[:key=value,...]",
        help=f"switch on an effect (repeatable); one of {', '.join(sorted(EFFECTS))}",
    )
    p.add_argument(
        "--static-s", type=float, default=None, help="length of the static recording (s)"
    )
    p.add_argument("--name", default=None, help="dataset name (default: the folder name)")
    p.add_argument(
        "--truth-seed",
        type=int,
        default=None,
        help="seed of the truth alone (default: --seed); sessions of one sensor unit share it",
    )
    p.set_defaults(func=_run_simulate)


def _run_simulate(args: argparse.Namespace) -> int:
    session = simulate(
        args.out_dir,
        preset=args.preset,
        seed=args.seed,
        effects=tuple(args.effect),
        static_s=args.static_s,
        name=args.name,
        truth_seed=args.truth_seed,
    )
    rows = {rec: len(log) for rec, log in session.logs.items()}
    print(f"wrote {args.out_dir}: dataset {session.name!r}, rows {rows}")
    return 0


def _add_apply(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "apply",
        help="calibrate an ingested recording with a calibration.json",
        description="Calibrate the acc/gyr/mag columns of an ingested recording (parquet, "
        "results/{dataset}/ingest/{recording}.parquet) to frame B with a calibration.json of "
        "this package, with every model term it has (a temperature term needs the recording's "
        "temperature column, within the calibrated span plus its margin); writes a parquet "
        "with the same rows and columns.",
    )
    p.add_argument("calibration", help="calibration.json (results/{dataset}/calibration.json)")
    p.add_argument("recording", help="ingested recording (parquet with imucal metadata)")
    p.add_argument("out", help="output parquet (written atomically)")
    p.add_argument(
        "--parameter-std",
        action="store_true",
        help="add per column the std of the calibrated value from the calibration's parameter "
        "covariance (columns acc_x_param_std, ...; the reading's own noise not included)",
    )
    p.set_defaults(func=_run_apply)


def _run_apply(args: argparse.Namespace) -> int:
    from imucal.io import read_calibration, read_recording, write_recording
    from imucal.pipeline.stages import apply_calibration

    table, metadata = read_recording(args.recording)
    calibrated, metadata = apply_calibration(
        table,
        metadata,
        read_calibration(args.calibration),
        parameter_std=args.parameter_std,
        source=args.recording,
    )
    write_recording(calibrated, args.out, metadata)
    print(f"wrote {args.out}: {len(calibrated)} rows calibrated with {args.calibration}")
    return 0


def _add_export(sub: argparse._SubParsersAction) -> None:
    from imucal.export.formats import FORMATS
    from imucal.export.model import ROSTOPIC

    p = sub.add_parser(
        "export",
        help="write a calibration and its noise for Kalibr, OpenVINS or ROS",
        description="Write the files one tool reads, under the tool's own names "
        "(docs/exports.md). kalibr: imu.yaml, of which Kalibr reads the noise densities, random "
        "walks, update_rate and rostopic, nothing else; and imucal-imu.yaml, our intrinsics (M, "
        "A, C_gyro_i) in the layout of Kalibr's results file <bag>-imu.yaml, for comparison: "
        "Kalibr estimates them itself and does not take them as input. openvins: "
        "kalibr_imu_chain.yaml, read through OpenCV: the noise values, model, Tw, R_IMUtoGYRO, "
        "Ta, R_IMUtoACC, Tg and rostopic (the biases are estimated online, not read). ros: "
        "imu_covariance.yaml, the sensor_msgs/Imu covariances and the calibration the driver "
        "applies (ROS applies none itself). Noise values are not inflated.",
    )
    p.add_argument("--format", required=True, choices=sorted(FORMATS), dest="fmt")
    p.add_argument("calibration", help="calibration.json (full or partial)")
    p.add_argument("noise", help="noise.json of the noise stage")
    p.add_argument("-o", "--out", default=".", help="output folder (default: the current one)")
    p.add_argument("--rostopic", default=ROSTOPIC, help=f"IMU topic (default {ROSTOPIC})")
    p.set_defaults(func=_run_export)


def _run_export(args: argparse.Namespace) -> int:
    from pathlib import Path

    from imucal.export import export_files
    from imucal.io import read_json

    files = export_files(
        args.fmt, read_json(args.calibration), read_json(args.noise), rostopic=args.rostopic
    )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (out / name).write_text(text, encoding="utf-8")
        print(f"wrote {out / name}")
    return 0


def _add_lookup(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "lookup",
        help="the calibration of a sensor unit valid at a date, from a fleet's store",
        description=(
            "Print the path of the calibration of serial SERIAL valid at DATE: the unit's "
            "latest session on or before it, from the store the fleet rule writes."
        ),
    )
    p.add_argument("store", help="store index (results/fleet/store.json)")
    p.add_argument("serial", help="sensor unit, as in the sample sheet")
    p.add_argument("date", help="YYYY-MM-DD")
    p.set_defaults(func=_run_lookup)


def _run_lookup(args: argparse.Namespace) -> int:
    from pathlib import Path

    from imucal.fleet import calibration_for
    from imucal.io import read_json

    if not Path(args.store).is_file():
        raise FileNotFoundError(
            f"{args.store}: no calibration store here. The target fleet writes it from a sample "
            "sheet (a TSV of dataset, path, serial, date, operator): set config fleet.sessions "
            "to the sheet and run snakemake --cores 2 fleet --configfile fleet.yaml "
            "(docs/fleet.md)"
        )
    entry = calibration_for(read_json(args.store), args.serial, args.date)
    print(entry["calibration"])
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with all subcommands."""
    from imucal import __version__

    parser = argparse.ArgumentParser(
        prog="imucal", description="IMU calibration on a 3-D rotation platform"
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_simulate(sub)
    _add_apply(sub)
    _add_export(sub)
    _add_lookup(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``imucal`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError) as err:  # bad input: the message says what and where
        print(f"imucal {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
