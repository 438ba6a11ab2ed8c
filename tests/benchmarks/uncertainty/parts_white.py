"""The check of the shipped standard deviations on independent parts, on simulated sessions with
white noise only: RMS z pooled over seeds per sensor and group, and how often a group is
inflated or warned about by chance.

Usage: python tests/benchmarks/uncertainty/parts_white.py tumble|full FIRST COUNT

``tumble``: a module turned by hand through 26 poses held 2-3 s each (the partial path: the
ellipsoid, the cube fit, pose to pose; cut in halves). ``full``: the paper's protocol of the
``random`` preset with a 60 s static recording (every segment cut in two).
"""

import sys

import numpy as np

from imucal.pipeline import partial
from imucal.pipeline.options import PipelineOptions
from imucal.pipeline.parts import check_full_session, check_partial_session
from imucal.segments.segmentation import segment_dataset
from imucal.sim import ProtocolConfig, TumbleConfig, make_truth, simulate_session, simulate_tumble
from imucal.sim.effects import stream_rng


def tumble_check(seed: int) -> dict:
    truth = make_truth("random", stream_rng(seed, "truth"))
    tables = {"poses": simulate_tumble(truth, seed, TumbleConfig(hold_s=(2.0, 3.0))).si_frame()}
    segments = segment_dataset(tables, fallback=True)
    # SI tables, ranges unknown, every other setting the schema's default
    options = PipelineOptions(truth.world.gravity_m_s2, {}, {}, None, ranges={})
    session = partial.Session(tables, segments, options, notes=segments.attrs["notes"])
    outcomes = partial.run_stages(session)
    final = partial.final_calibration(outcomes, options)
    return check_partial_session(
        session,
        [o.summary() for o in outcomes],
        {s: e["calibration"] for s, e in final["sensors"].items()},
        {o.name: o.artifact for o in outcomes if o.status == "run"},
    )


def full_check(seed: int) -> dict:
    truth = make_truth("random", stream_rng(seed, "truth"))
    session = simulate_session(truth, seed, ProtocolConfig(static_s=60.0))
    tables = {n: session.si_frame(n) for n in ("rotation3d", "cube", "ratetable", "static")}
    table = {
        "axes": list(session.config.ratetable_axes),
        "rates_dps": list(session.config.rates_dps),
    }
    segments = segment_dataset(tables, ratetable=table, fallback=True)
    counts = dict.fromkeys(("acc", "gyr", "mag"), 32767)
    options = PipelineOptions(truth.world.gravity_m_s2, session.sensitivity, counts, table, 1.0)
    return check_full_session(tables, segments, options)


kind, first, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
check = {"tumble": tumble_check, "full": full_check}[kind]
pooled: dict = {}
inflated = warned = sensors = 0
for seed in range(first, first + count):
    result = check(seed)
    for sensor, entry in result["sensors"].items():
        sensors += 1
        inflated += max(entry["inflation"].values()) > 1.0
        warned += bool(entry["warnings"])
        for warning in entry["warnings"]:
            print(f"  seed {seed} {sensor}: {warning}")
        for group, found in (entry.get("parts") or {}).get("groups", {}).items():
            if found["rms_z"] is not None:
                chi2, dof = pooled.get((sensor, entry["stage"], group), (0.0, 0))
                pooled[(sensor, entry["stage"], group)] = (
                    chi2 + found["rank"] * found["rms_z"] ** 2,
                    dof + found["rank"],
                )
    print(f"seed {seed} done", flush=True)
print(f"{kind}, seeds {first}-{first + count - 1}: RMS z pooled over the seeds (dof)")
for (sensor, stage, group), (chi2, dof) in pooled.items():
    print(f"  {sensor} {stage} {group}: {np.sqrt(chi2 / dof):.3f} ({dof})")
print(f"sensors inflated {inflated} of {sensors}, warned {warned} of {sensors}")
