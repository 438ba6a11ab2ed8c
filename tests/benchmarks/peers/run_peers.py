"""Peers benchmark: our methods beside the peers as they ship, on the public recordings.

Run from the repository root::

    python tests/benchmarks/peers/run_peers.py

Each peer runs from PyPI in a venv of its own (:mod:`venvs`, under ``.cache/``):

* mad-lab-fau's ``imucal`` (Ferraris; its import name clashes with ours): ``pypi_adapter.py``
  on the two Ferraris sessions of ``../shared/data/real/mad-lab-fau__imucal``, our methods on
  the same sections here, both scored on data neither was fitted to; our cube fit and
  pose-to-pose gyroscope on the imu_tk recording (Xsens MTi);
* ``magcal`` (magnetometer ellipsoid): ``magcal_adapter.py`` beside our ellipsoid fit on
  every public recording with a magnetometer, held out (:mod:`mag_peers`);
* scikit-diveMove's ``IMUcalibrate`` (its wheel without R): ``skdivemove_adapter.py`` on the
  CATS recording, against the port of ``build_tmodels`` (:mod:`imucalibrate_check`); the
  thermal comparison itself is the workflow's hold-out, whose tables ``thermal_tables.py``
  writes.

Results go to ``tests/benchmarks/peers/results.json``; the Markdown tables are printed and
written into the generated blocks of docs/comparison.md (and the CATS blocks of
docs/real-recordings.md and README.md when the hold-out's JSON is there).

It exits with status 0 and a "SKIPPED" message when ``../shared`` is absent or pip cannot
install a peer (no network).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from imucal import errormodel
from imucal.fits.accelerometer import fit_cube
from imucal.fits.ferraris import FACE_DIRECTIONS, fit_known_orientations, fit_known_rotations
from imucal.fits.posetopose import fit_pose_to_pose, gravity_direction_errors
from imucal.ingest import ingest_recording

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the benchmark's own modules
import imucalibrate_check  # noqa: E402
import mag_peers  # noqa: E402
import thermal_tables  # noqa: E402
import venvs  # noqa: E402
from venvs import peer_env  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
HERE = Path(__file__).resolve().parent
SHARED = REPO.parent / "shared" / "data" / "real"
FERRARIS_DIR = SHARED / "mad-lab-fau__imucal"
IMUTK_DIR = SHARED / "Kyle-ak__imu_tk"
CATS_FILE = SHARED / "spluque__scikit-diveMove" / "cats_temperature_calib.nc"
COMPARISON = REPO / "docs" / "comparison.md"
WORK = REPO / ".cache" / "peers"
RESULTS = HERE / "results.json"

FACES = tuple(FACE_DIRECTIONS)
ROTATIONS = ("x_rot", "y_rot", "z_rot")
ACC_COLS = ["acc_x", "acc_y", "acc_z"]
GYR_COLS = ["gyr_x", "gyr_y", "gyr_z"]
#: The PyPI tool's default gravity; used by both tools on the Ferraris sessions.
G_FERRARIS = 9.81
#: imu_tk's test_imu_calib.cpp: gravity, acc zero (counts) and gyro scale guess (rad/s per count).
G_IMUTK = 9.81744
IMUTK_ACC_ZERO = 32768.0
IMUTK_GYR_SCALE = 1.0 / 6258.0
IMUTK_INIT_STATIC_S = 50.0
#: Nominal sensitivities of the annotated session (counts): +-16 g and +-2000 deg/s ranges.
ANNOTATED_ACC_PER_G = 2048.0
ANNOTATED_GYR_PER_DPS = 16.4
REPEATS = 20


def skip(reason: str) -> None:
    print(f"SKIPPED: {reason}")
    sys.exit(0)


# ------------------------------------------------------------------------------------------------
# Data (read directly with pandas / numpy, independent of the package's readers)
# ------------------------------------------------------------------------------------------------


def load_example() -> dict:
    """Session 1: one continuous recording, m/s^2 and deg/s, 102.4 Hz, section list."""
    table = pd.read_csv(FERRARIS_DIR / "example_ferraris_session.csv")
    sections = json.loads((FERRARIS_DIR / "example_ferraris_session_list.json").read_text())
    rate = 102.4
    return {
        "name": "example_ferraris_session",
        "t_s": np.arange(len(table)) / rate,
        "acc": table[ACC_COLS].to_numpy(float),
        "gyr": np.radians(table[GYR_COLS].to_numpy(float)),
        "sections": {k: (v["start"], v["end"]) for k, v in sections.items()},
        "blocks": [(0, len(table))],
        "rate_hz": rate,
        "rotation_sign": -1.0,
        "acc_note": "m/s^2 as recorded",
    }


def load_annotated() -> dict:
    """Session 2: 9 parts cut from a recording, counts, 204.8 Hz; parts are separate blocks."""
    table = pd.read_csv(FERRARIS_DIR / "annotated_session.csv").sort_values("samples")
    table = table.reset_index(drop=True)
    rate = 204.8
    parts = table["part"].to_numpy()
    change = np.flatnonzero(parts[1:] != parts[:-1]) + 1
    bounds = np.concatenate([[0], change, [len(table)]])
    blocks = list(zip(bounds[:-1], bounds[1:]))
    return {
        "name": "annotated_session",
        "t_s": table["samples"].to_numpy(float) / rate,
        "acc": table[ACC_COLS].to_numpy(float) * G_FERRARIS / ANNOTATED_ACC_PER_G,
        "gyr": np.radians(table[GYR_COLS].to_numpy(float) / ANNOTATED_GYR_PER_DPS),
        "sections": {parts[a]: (int(a), int(b)) for a, b in blocks},
        "blocks": blocks,
        "rate_hz": rate,
        # the raw rotations integrate to +360 deg here: see docs/comparison.md
        "rotation_sign": 1.0,
        "acc_note": f"counts x {G_FERRARIS}/{ANNOTATED_ACC_PER_G:g} (nominal +-16 g)",
    }


def load_imutk() -> dict:
    acc = np.loadtxt(IMUTK_DIR / "xsens_acc.mat")
    gyr = np.loadtxt(IMUTK_DIR / "xsens_gyro.mat")
    if not np.allclose(acc[:, 0], gyr[:, 0]):
        raise ValueError("imu_tk: accelerometer and gyroscope timestamps differ")
    return {"t_s": acc[:, 0], "acc_counts": acc[:, 1:], "gyr_counts": gyr[:, 1:]}


# ------------------------------------------------------------------------------------------------
# Metric functions (pure; tested on a synthetic session in tests/test_peers_metrics.py)
# ------------------------------------------------------------------------------------------------


def find_static(
    gyr: np.ndarray,
    reference: np.ndarray,
    blocks: Sequence[tuple[int, int]],
    window: int,
    min_samples: int,
    factor: float = 3.0,
) -> list[tuple[int, int]]:
    """Static stretches by a moving-variance detector on the gyroscope.

    Parameters
    ----------
    gyr : ndarray, shape (n, 3)
        Gyroscope, any unit.
    reference : ndarray of bool, shape (n,)
        Samples known to be static; the threshold is ``factor`` times the median of the
        window variance (sum over axes) there.
    blocks : sequence of (start, end)
        Contiguous blocks; windows never span two blocks.
    window : int
        Centred window, samples.
    min_samples : int
        Shortest stretch kept.

    Returns
    -------
    list of (start, end)
        Half-open index ranges, in time order.
    """
    stat = np.full(len(gyr), np.inf)
    half = window // 2
    for a, b in blocks:
        x = gyr[a:b]
        if len(x) < window:
            continue
        c1 = np.cumsum(np.vstack([np.zeros(3), x]), axis=0)
        c2 = np.cumsum(np.vstack([np.zeros(3), x**2]), axis=0)
        s1 = c1[window:] - c1[:-window]
        s2 = c2[window:] - c2[:-window]
        var = ((s2 - s1**2 / window) / (window - 1)).sum(axis=1)
        stat[a + half : a + half + len(var)] = var
    threshold = factor * np.median(stat[reference & np.isfinite(stat)])
    quiet = stat < threshold
    out = []
    for a, b in blocks:
        q = np.concatenate([[False], quiet[a:b], [False]])
        edges = np.flatnonzero(np.diff(q.astype(int)))
        for s, e in zip(edges[::2], edges[1::2]):
            if e - s >= min_samples:
                out.append((a + s, a + e))
    return out


def magnitude_rms(acc: np.ndarray, stretches: Sequence[tuple[int, int]], g: float) -> float:
    """Per-sample RMS of ``|a| - g`` (m/s^2) over the samples of ``stretches``."""
    idx = np.concatenate([np.arange(a, b) for a, b in stretches])
    return float(np.sqrt(np.mean((np.linalg.norm(acc[idx], axis=1) - g) ** 2)))


def consecutive_pairs(
    stretches: Sequence[tuple[int, int]], blocks: Sequence[tuple[int, int]]
) -> list[tuple[int, int]]:
    """Indices (k, k + 1) of consecutive static stretches in the same contiguous block."""
    block_of = [next(i for i, (a, b) in enumerate(blocks) if a <= s < b) for s, _ in stretches]
    return [(k, k + 1) for k in range(len(stretches) - 1) if block_of[k] == block_of[k + 1]]


def pose_problem(
    t_s: np.ndarray,
    acc_cal: np.ndarray,
    gyr: np.ndarray,
    stretches: Sequence[tuple[int, int]],
    pairs: Sequence[tuple[int, int]],
) -> tuple[np.ndarray, np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """Start / end gravity directions (mean calibrated acc) and the gyro between the poses.

    Each interval runs from the last sample of pose k to the first sample of pose k + 1.
    """
    means = np.array([acc_cal[a:b].mean(axis=0) for a, b in stretches])
    start = np.array([means[i] for i, _ in pairs])
    end = np.array([means[j] for _, j in pairs])
    intervals = [
        (
            t_s[stretches[i][1] - 1 : stretches[j][0] + 1],
            gyr[stretches[i][1] - 1 : stretches[j][0] + 1],
        )
        for i, j in pairs
    ]
    return start, end, intervals


def angle_summary(errors_deg: np.ndarray) -> dict:
    e = np.asarray(errors_deg, dtype=float)
    return {"n": int(e.size), "rms_deg": float(np.sqrt(np.mean(e**2))), "max_deg": float(np.max(e))}


def timed(func: Callable[[], object], repeats: int = REPEATS) -> tuple[object, float]:
    """Result of ``func()`` and its fastest run time over ``repeats`` calls, s."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = func()
        best = min(best, time.perf_counter() - t0)
    return out, float(best)


# ------------------------------------------------------------------------------------------------
# Peer (PyPI imucal) in its own environment
# ------------------------------------------------------------------------------------------------


def run_peer(python: Path, session: str, expected_angle_deg: float) -> tuple[dict, dict]:
    WORK.mkdir(parents=True, exist_ok=True)
    prefix = WORK / f"{session}_{expected_angle_deg:+.0f}"
    subprocess.run(
        [
            str(python),
            str(HERE / "pypi_adapter.py"),
            session,
            str(FERRARIS_DIR),
            str(expected_angle_deg),
            str(prefix),
        ],
        check=True,
        env=peer_env(),
        cwd=WORK,
    )
    info = json.loads(prefix.with_suffix(".json").read_text())
    arrays = np.load(prefix.with_suffix(".npz"))
    return info, {"acc": arrays["acc"], "gyr": arrays["gyr"]}


# ------------------------------------------------------------------------------------------------
# Ferraris sessions
# ------------------------------------------------------------------------------------------------


def our_ferraris(s: dict, faces: Sequence[str] = FACES):
    acc, gyr, sec = s["acc"], s["gyr"], s["sections"]
    positions = [acc[slice(*sec[k])] for k in faces]
    directions = np.array([FACE_DIRECTIONS[k] for k in faces])
    acc_fit = fit_known_orientations(positions, directions, G_FERRARIS, labels=list(faces))
    static_gyr = [gyr[slice(*sec[k])] for k in FACES]
    bias = np.vstack(static_gyr).mean(axis=0)
    noise = np.sqrt(
        sum(((x - x.mean(0)) ** 2).sum(0) for x in static_gyr) / sum(len(x) - 1 for x in static_gyr)
    )
    n_static = sum(len(x) for x in static_gyr)
    rotations = [(s["t_s"][slice(*sec[k])], gyr[slice(*sec[k])]) for k in ROTATIONS]
    known = s["rotation_sign"] * 2 * np.pi * np.eye(3)
    gyr_fit = fit_known_rotations(
        rotations,
        known,
        bias,
        noise_std_rad_s=noise,
        bias_std_rad_s=noise / np.sqrt(n_static),
        labels=list(ROTATIONS),
    )
    return acc_fit, gyr_fit


def in_sections(n: int, sections: dict, names: Sequence[str]) -> np.ndarray:
    mask = np.zeros(n, dtype=bool)
    for k in names:
        mask[slice(*sections[k])] = True
    return mask


def held_out_stretches(stretches, mask_fitted: np.ndarray, min_samples: int):
    """Parts of static stretches outside the fitted samples (longest run per stretch)."""
    out = []
    for a, b in stretches:
        free = ~mask_fitted[a:b]
        q = np.concatenate([[False], free, [False]])
        edges = np.flatnonzero(np.diff(q.astype(int)))
        for s, e in zip(edges[::2], edges[1::2]):
            if e - s >= min_samples:
                out.append((a + s, a + e))
    return out


def ferraris_benchmark(s: dict, peer: dict, peer_arrays: dict) -> dict:
    n = len(s["acc"])
    sec = s["sections"]
    window = max(5, int(round(0.15 * s["rate_hz"])))
    min_samples = int(round(0.2 * s["rate_hz"]))
    face_mask = in_sections(n, sec, FACES)
    stretches = find_static(s["gyr"], face_mask, s["blocks"], window, min_samples)
    (acc_fit, gyr_fit), t_ours = timed(lambda: our_ferraris(s))
    ours_acc = acc_fit.calibration.apply(s["acc"], "m/s^2")
    ours_gyr = gyr_fit.calibration.apply(s["gyr"], "rad/s")
    peer_acc = peer_arrays["acc"]
    peer_gyr = np.radians(peer_arrays["gyr"])

    faces = [sec[k] for k in FACES]
    held = held_out_stretches(stretches, face_mask, min_samples)
    in_rotation = in_sections(n, sec, ROTATIONS)
    held_in_rot = [(a, b) for a, b in held if in_rotation[a:b].all()]
    # leave-one-face-out: ours refit on 5 faces, scored on the sixth
    lopo = []
    for k in FACES:
        rest = [f for f in FACES if f != k]
        fit5, _ = our_ferraris(s, rest)
        cal5 = fit5.calibration.apply(s["acc"][slice(*sec[k])], "m/s^2")
        lopo.append(np.linalg.norm(cal5, axis=1) - G_FERRARIS)
    lopo = np.concatenate(lopo)

    pairs = consecutive_pairs(stretches, s["blocks"])
    outside = [
        p for p in pairs if not in_rotation[stretches[p[0]][1] - 1 : stretches[p[1]][0] + 1].any()
    ]
    gravity = {}
    for name, acc_cal, gyr_cal in (
        ("ours", ours_acc, ours_gyr),
        ("pypi", peer_acc, peer_gyr),
        ("raw", s["acc"], s["gyr"] - gyr_fit.calibration.bias),
    ):
        res = {}
        for label, subset in (("all", pairs), ("outside_rotations", outside)):
            if subset:
                st, en, iv = pose_problem(s["t_s"], acc_cal, gyr_cal, stretches, subset)
                res[label] = angle_summary(gravity_direction_errors(st, en, iv))
        gravity[name] = res
    # our pose-to-pose gyro (acc: ours), scored by leave-one-interval-out
    st, en, iv = pose_problem(s["t_s"], ours_acc, s["gyr"], stretches, pairs)
    p2p: dict = {}
    try:
        full_fit, t_p2p = timed(
            lambda: fit_pose_to_pose(st, en, iv, gyr_fit.calibration.bias), repeats=3
        )
        loo = []
        for k in range(len(iv)):
            keep = [i for i in range(len(iv)) if i != k]
            f = fit_pose_to_pose(
                st[keep], en[keep], [iv[i] for i in keep], gyr_fit.calibration.bias
            )
            loo.append(
                gravity_direction_errors(
                    st[k : k + 1], en[k : k + 1], [iv[k]], f.calibration.matrix, f.calibration.bias
                )[0]
            )
        p2p = {
            "in_sample": angle_summary(full_fit.angle_errors_deg),
            "leave_one_interval_out": angle_summary(np.array(loo)),
            "matrix": full_fit.calibration.matrix.tolist(),
            "fit_time_s": t_p2p,
        }
    except ValueError as exc:
        p2p = {"error": str(exc)}
    try:
        fit_cube([s["acc"][a:b] for a, b in stretches], G_FERRARIS)
        cube = "ran"
    except ValueError as exc:
        cube = f"refused: {exc}"

    peer_matrix_acc = np.linalg.inv(np.array(peer["R_a"])) @ np.linalg.inv(np.array(peer["K_a"]))
    peer_matrix_gyr = np.linalg.inv(np.array(peer["R_g"])) @ np.linalg.inv(np.array(peer["K_g"]))
    return {
        "session": s["name"],
        "acc_input": s["acc_note"],
        "static_stretches": len(stretches),
        "held_out_stretches": len(held),
        "held_out_stretches_in_rotations": len(held_in_rot),
        "held_out_samples": int(sum(b - a for a, b in held)),
        "acc": {
            "in_sample_rms_m_s2": {
                "raw": magnitude_rms(s["acc"], faces, G_FERRARIS),
                "ours": magnitude_rms(ours_acc, faces, G_FERRARIS),
                "pypi": magnitude_rms(peer_acc, faces, G_FERRARIS),
            },
            "held_out_pauses_rms_m_s2": {
                "raw": magnitude_rms(s["acc"], held, G_FERRARIS),
                "ours": magnitude_rms(ours_acc, held, G_FERRARIS),
                "pypi": magnitude_rms(peer_acc, held, G_FERRARIS),
            }
            if held
            else None,
            "ours_leave_one_face_out_rms_m_s2": float(np.sqrt(np.mean(lopo**2))),
        },
        "gravity_direction": gravity,
        "intervals": {"all": len(pairs), "outside_rotations": len(outside)},
        "ours_pose_to_pose_gyro": p2p,
        "cube_fit_on_static_stretches": cube,
        "params": {
            "ours": {"acc": acc_fit.calibration.to_dict(), "gyr": gyr_fit.calibration.to_dict()},
            "pypi": {
                "acc_matrix": peer_matrix_acc.tolist(),
                "acc_bias": peer["b_a"],
                "gyr_matrix_from_deg_s_to_deg_s": peer_matrix_gyr.tolist(),
                "gyr_bias": peer["b_g"],
                "K_ga": peer["K_ga"],
                "expected_angle_deg": peer["expected_angle_deg"],
            },
        },
        "run_time_s": {"ours_acc_plus_gyr": t_ours, "pypi_compute": peer["compute_time_s_min"]},
    }


# ------------------------------------------------------------------------------------------------
# imu_tk recording
# ------------------------------------------------------------------------------------------------


def imutk_benchmark() -> dict:
    d = load_imutk()
    t = d["t_s"]
    init = (t > t[0] + 1.0) & (t < t[0] + IMUTK_INIT_STATIC_S - 1.0)
    gyr_bias_counts = d["gyr_counts"][init].mean(axis=0)
    gyr = (d["gyr_counts"] - gyr_bias_counts) * IMUTK_GYR_SCALE  # nominal rad/s, bias removed
    centred = d["acc_counts"] - IMUTK_ACC_ZERO
    acc_scale = G_IMUTK / np.linalg.norm(centred[init].mean(axis=0))
    acc = centred * acc_scale  # nominal m/s^2 (one-point scale from the initial static)
    blocks = [(0, len(t))]
    stretches = find_static(gyr, init, blocks, window=100, min_samples=100)
    positions = [acc[a:b] for a, b in stretches]
    cube, t_cube = timed(lambda: fit_cube(positions, G_IMUTK), repeats=3)
    acc_cal = errormodel.apply(cube.upper, cube.bias, acc)
    lopo = []
    for k in range(len(positions)):
        f = fit_cube(positions[:k] + positions[k + 1 :], G_IMUTK)
        cal = errormodel.apply(f.upper, f.bias, positions[k])
        lopo.append(np.linalg.norm(cal, axis=1) - G_IMUTK)
    lopo = np.concatenate(lopo)
    pairs = consecutive_pairs(stretches, blocks)
    st, en, iv = pose_problem(t, acc_cal, gyr, stretches, pairs)
    fit, t_p2p = timed(lambda: fit_pose_to_pose(st, en, iv, np.zeros(3)), repeats=3)
    loo = []
    for k in range(len(iv)):
        keep = [i for i in range(len(iv)) if i != k]
        f = fit_pose_to_pose(st[keep], en[keep], [iv[i] for i in keep], np.zeros(3))
        loo.append(
            gravity_direction_errors(st[k : k + 1], en[k : k + 1], [iv[k]], f.calibration.matrix)[0]
        )
    dt = np.diff(t)
    return {
        "samples": len(t),
        "dt_s": {"median": float(np.median(dt)), "min": float(dt.min()), "max": float(dt.max())},
        "static_stretches": len(stretches),
        "intervals": len(pairs),
        "nominal": {
            "acc": f"(counts - 32768) x {acc_scale:.6g} m/s^2 per count (|initial static| = g)",
            "gyr": "(counts - initial-static mean) / 6258 rad/s",
        },
        "acc": {
            "raw_rms_m_s2": magnitude_rms(acc, stretches, G_IMUTK),
            "cube_in_sample_rms_m_s2": magnitude_rms(acc_cal, stretches, G_IMUTK),
            "cube_leave_one_pose_out_rms_m_s2": float(np.sqrt(np.mean(lopo**2))),
            "cube_chi2_dof": [cube.chi2, cube.dof],
            "upper": cube.upper.tolist(),
            "bias_m_s2": cube.bias.tolist(),
        },
        "gravity_direction": {
            "nominal_gyro": angle_summary(fit.angle_errors_before_deg),
            "pose_to_pose_in_sample": angle_summary(fit.angle_errors_deg),
            "pose_to_pose_leave_one_interval_out": angle_summary(np.array(loo)),
        },
        "gyro": {
            "matrix_per_nominal": fit.calibration.matrix.tolist(),
            "scale": fit.calibration.to_dict()["scale"],
            "scale_std": fit.parameter_std[:3].tolist(),
            "xi_rad": fit.calibration.to_dict()["xi_rad"],
            "alpha_rad": fit.calibration.to_dict()["alpha_rad"],
            "excitation_rad": fit.excitation_rad.tolist(),
        },
        "run_time_s": {"cube": t_cube, "pose_to_pose": t_p2p},
    }


# ------------------------------------------------------------------------------------------------


def tables(results: dict) -> str:
    lines = [
        "| session | figure (m/s^2 or deg) | raw | ours | PyPI imucal |",
        "|---|---|---|---|---|",
    ]
    for r in results["ferraris"]:
        a, gd = r["acc"], r["gravity_direction"]
        name = r["session"]
        ins = a["in_sample_rms_m_s2"]
        lines.append(
            f"| {name} | in-sample static abs(a)-g RMS, 6 faces | {ins['raw']:.4f} | "
            f"{ins['ours']:.4f} | {ins['pypi']:.4f} |"
        )
        lines.append(
            f"| {name} | held-out: leave-one-face-out abs(a)-g RMS | | "
            f"{a['ours_leave_one_face_out_rms_m_s2']:.4f} | not refittable on 5 faces |"
        )
        if a["held_out_pauses_rms_m_s2"]:
            h = a["held_out_pauses_rms_m_s2"]
            lines.append(
                f"| {name} | held-out: abs(a)-g RMS on {r['held_out_stretches']} static "
                f"stretches outside the faces | {h['raw']:.4f} | {h['ours']:.4f} | "
                f"{h['pypi']:.4f} |"
            )
        for label in ("all", "outside_rotations"):
            if label in gd["ours"]:
                o, p, w = gd["ours"][label], gd["pypi"][label], gd["raw"][label]
                lines.append(
                    f"| {name} | gravity direction pose to pose, {label} ({o['n']} intervals), "
                    f"RMS / max deg | {w['rms_deg']:.3f} / {w['max_deg']:.3f} | "
                    f"{o['rms_deg']:.3f} / {o['max_deg']:.3f} | {p['rms_deg']:.3f} / {p['max_deg']:.3f} |"
                )
        p2p = r["ours_pose_to_pose_gyro"]
        if "leave_one_interval_out" in p2p:
            q = p2p["leave_one_interval_out"]
            lines.append(
                f"| {name} | ours pose-to-pose gyro, leave-one-interval-out RMS / max deg "
                f"| | {q['rms_deg']:.3f} / {q['max_deg']:.3f} | |"
            )
        rt = r["run_time_s"]
        lines.append(
            f"| {name} | fit run time, s (fastest of {REPEATS}) | | "
            f"{rt['ours_acc_plus_gyr']:.4f} | {rt['pypi_compute']:.4f} |"
        )
    m = results["imu_tk"]
    g = m["gravity_direction"]
    lines += [
        "",
        "| imu_tk (Xsens MTi) | raw / nominal | calibrated |",
        "|---|---|---|",
        f"| static abs(a)-g RMS, m/s^2, {m['static_stretches']} poses, in-sample | "
        f"{m['acc']['raw_rms_m_s2']:.4f} | {m['acc']['cube_in_sample_rms_m_s2']:.4f} |",
        f"| static abs(a)-g RMS, leave-one-pose-out | | "
        f"{m['acc']['cube_leave_one_pose_out_rms_m_s2']:.4f} |",
        f"| gravity direction pose to pose ({g['nominal_gyro']['n']} intervals), RMS / max deg, "
        f"in-sample | {g['nominal_gyro']['rms_deg']:.3f} / {g['nominal_gyro']['max_deg']:.3f} | "
        f"{g['pose_to_pose_in_sample']['rms_deg']:.3f} / {g['pose_to_pose_in_sample']['max_deg']:.3f} |",
        f"| the same, leave-one-interval-out | | "
        f"{g['pose_to_pose_leave_one_interval_out']['rms_deg']:.3f} / "
        f"{g['pose_to_pose_leave_one_interval_out']['max_deg']:.3f} |",
    ]
    return "\n".join(lines)


def magnetometer_peers() -> list[dict]:
    """magcal and our ellipsoid fit, held out, on every public magnetometer recording."""
    python = venvs.ensure("magcal", REPO)
    out = []
    for name in mag_peers.DATASETS:
        work = WORK / "magcal" / name

        def peer(samples, fold, work=work):
            return mag_peers.run_magcal(python, samples, work / f"fold{fold}",
                                        HERE / "magcal_adapter.py", peer_env())  # fmt: skip

        out.append(mag_peers.mag_benchmark(name, REPO, ingest_recording, peer))
    return out


def imucalibrate_reproduction() -> dict:
    """scikit-diveMove's own build_tmodels (its wheel) against the port, on its CATS file."""
    python = venvs.ensure("skdivemove", REPO)
    WORK.mkdir(parents=True, exist_ok=True)
    target = WORK / "skdivemove_models.json"
    subprocess.run([str(python), str(HERE / "skdivemove_adapter.py"), str(CATS_FILE),
                    str(target)], check=True, env=peer_env(), cwd=WORK)  # fmt: skip
    peer = json.loads(target.read_text())
    periods = imucalibrate_check.load_cats(CATS_FILE)
    port = imucalibrate_check.port_models(periods, None) + imucalibrate_check.port_models(
        periods, 10.0
    )
    return {
        "peer_versions": venvs.versions(
            python, ["scikit-diveMove", "statsmodels", "pandas", "xarray", "numpy", "scipy"]
        ),  # fmt: skip
        "peer": peer,
        "port_vs_peer": imucalibrate_check.compare(peer["models"], port),
    }


def main() -> None:
    for folder in (FERRARIS_DIR, IMUTK_DIR, CATS_FILE.parent):
        if not folder.exists():
            skip(f"shared data absent: expected {folder}")
    python = venvs.ensure("imucal", REPO)
    results: dict = {"ferraris": [], "peer_variants": {}}
    for loader, session in ((load_example, "example"), (load_annotated, "annotated")):
        s = loader()
        angle = 360.0 * s["rotation_sign"]
        peer, arrays = run_peer(python, session, angle)
        results["ferraris"].append(ferraris_benchmark(s, peer, arrays))
        if angle > 0:
            # the PyPI default (-360, as its own example and test use on this session)
            default, _ = run_peer(python, session, -360.0)
            rg = np.array(default["R_g"])
            results["peer_variants"][session] = {
                "default_expected_angle_-360_det_R_g": float(np.linalg.det(rg)),
                "R_g_diagonal": np.diag(rg).tolist(),
            }
    results["imu_tk"] = imutk_benchmark()
    results["magnetometer"] = magnetometer_peers()
    results["magcal_version"] = venvs.versions(venvs.ensure("magcal", REPO), ["magcal"])
    results["imucalibrate"] = imucalibrate_reproduction()
    RESULTS.write_text(json.dumps(results, indent=1))
    text = tables(results)
    ferraris, imutk = text.split("\n\n", 1)
    mag = mag_peers.table(results["magnetometer"])
    reproduction = imucalibrate_check.table(results["imucalibrate"])
    print(text, mag, reproduction, sep="\n\n")
    thermal_tables.replace_block(COMPARISON, "peers-ferraris", ferraris)
    thermal_tables.replace_block(COMPARISON, "peers-imutk", imutk)
    thermal_tables.replace_block(COMPARISON, "peers-magnetometer", mag)
    thermal_tables.replace_block(COMPARISON, "peers-imucalibrate", reproduction)
    print(f"\nwrote {RESULTS.relative_to(REPO)} and the tables of {COMPARISON.relative_to(REPO)}")
    thermal_tables.main()


if __name__ == "__main__":
    main()
