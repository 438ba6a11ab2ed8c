"""magcal (PyPI, Lundeen Cahilly) beside our ellipsoid fit on every public magnetometer recording.

``magcal_adapter.py`` runs the peer in its own venv: ``MagnetometerCalibrator`` of
``magcal.core`` (version 1.0.1), its data loaded from a JSON list as its ``magcal from-file``
command does, ``calibrate("ellipsoid")`` (the default method) and the calibrated field
``transform_matrix @ (m - center)`` it writes into its C header. What it does (read from the
wheel): the centre is the mean of the samples (not fitted), the centred samples fit
``x' A x = 1`` without linear terms by least squares, and the transform is the symmetric
square root of ``A``; it refuses fewer than 500 samples.

Held out: each recording's magnetometer samples are cut into ten runs of consecutive samples;
the fit takes the even runs and the odd ones are scored, then the other way round (two folds,
each sample scored once, by a fit that did not see it or its run). Figures on the held-out
samples (the field normalised by the dataset's ``field_norm_t``, so both target a radius of 1):

* the RMS of ``|m| - 1`` (as the method ships its scale) and the spread ``std(|m|) / mean(|m|)``
  (magcal's own quality score, free of the scale);
* where the recording holds an accelerometer, a second direction reference: the angle between
  the calibrated field and the specific force at quasi-static samples (``| |a| - g | < 2 %`` of
  g, and ``|w| < 0.1 rad/s`` where there is a gyroscope) must stay the field's dip; its
  spread (std, deg) is the direction figure. Our step 1 is upper triangular (its frame is then
  aligned by step 2, which needs the platform's turns); for this figure ours is taken in the
  symmetric form ``sqrt(S'^T S')`` that magcal ships, so the figure compares the fitted
  ellipsoids, not a choice of frame.

"ours" is the fit as the pipeline ships it (the algebraic solution refined by
Levenberg-Marquardt, refused where that does not converge); "ours, algebraic only" is the
same without the refinement (``refine_lm=False``, what the refusal suggests).
"""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.linalg import sqrtm

from imucal.columns import ACC, GYR, MAG
from imucal.fits.magnetometer import fit_ellipsoid
from imucal.io.dataset import read_dataset

#: Our dataset folders with magnetometer data (data/real): their label and the recordings a
#: user would give a magnetometer calibration (magcal asks for rotations through all
#: orientations; sunsided's static recordings are left out, the CATS tag has only its poses).
DATASETS = {
    "sunsided_sensor_fusion": ("sunsided (HMC5883L)", ("tumble", "rotation3d")),
    "tomisuarez2_mag": ("tomisuarez2 MagnetometerCalibration (QMC5883L)", ("tumble",)),
    "ck_explorer": ("CK-Explorer (unnamed)", ("tumble",)),
    "dlaidig_broad": ("dlaidig BROAD trial 07 (myon aktos-t)", ("tumble",)),
    "spluque_cats_thermal": ("CATS tag (three static poses only)", ("poses",)),
}
RUNS = 10
STATIC_G_FRACTION = 0.02
STATIC_RATE_RAD_S = 0.1


def runs_of(n: int, runs: int = RUNS) -> np.ndarray:
    """The run (0 .. runs - 1) of each of ``n`` consecutive samples, equal counts."""
    return np.minimum(np.arange(n) * runs // n, runs - 1)


def norm_figures(field: np.ndarray) -> dict:
    """RMS of ``|m| - 1`` and ``std(|m|) / mean(|m|)`` of calibrated samples (n, 3)."""
    r = np.linalg.norm(field, axis=1)
    return {
        "norm_rms": float(np.sqrt(np.mean((r - 1.0) ** 2))),
        "spread": float(r.std() / r.mean()),
    }


def dip_spread_deg(field: np.ndarray, acc: np.ndarray) -> float:
    """Std (deg) of the angle between the field and the specific force, samples (n, 3)."""
    cos = np.sum(field * acc, axis=1) / (
        np.linalg.norm(field, axis=1) * np.linalg.norm(acc, axis=1)
    )
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).std(ddof=1))


def quasi_static(table, gravity: float) -> np.ndarray:
    """Rows with a fresh magnetometer sample where the module is nearly at rest."""
    mag = table[list(MAG)].to_numpy(float)
    ok = np.isfinite(mag).all(axis=1)
    if not all(c in table.columns for c in ACC):
        return np.zeros(len(table), bool)
    acc = table[list(ACC)].to_numpy(float)
    ok &= np.isfinite(acc).all(axis=1)
    ok &= np.abs(np.linalg.norm(acc, axis=1) - gravity) < STATIC_G_FRACTION * gravity
    if all(c in table.columns for c in GYR):
        gyr = table[list(GYR)].to_numpy(float)
        ok &= np.isfinite(gyr).all(axis=1) & (np.linalg.norm(gyr, axis=1) < STATIC_RATE_RAD_S)
    return ok


def on_every_row(table):
    """The accelerometer and gyroscope interpolated in time onto every row (streams of their
    own leave them NaN on the magnetometer's rows)."""
    out = table.copy()
    t = table["t_s"].to_numpy(float)
    for column in (*ACC, *GYR):
        if column in table.columns:
            v = table[column].to_numpy(float)
            ok = np.isfinite(v)
            if ok.sum() > 1 and not ok.all():
                out[column] = np.interp(t, t[ok], v[ok])
    return out


def recordings_with_mag(name: str, repo: Path, ingest: Callable) -> dict:
    """Recording -> (mag (n, 3), acc or None (n, 3), quasi-static mask (n,)) of one dataset,
    the rows with a fresh magnetometer sample, in time order."""
    dataset = read_dataset(repo / "data" / "real" / name)
    out = {}
    for recording in DATASETS[name][1]:
        path = dataset.recordings[recording]
        table, _ = ingest(path, recording=recording, dataset=dataset, imucal_version="bench")
        table = on_every_row(table)
        if not all(c in table.columns for c in MAG):
            continue
        fresh = np.isfinite(table[list(MAG)].to_numpy(float)).all(axis=1)
        if not fresh.any():
            continue
        static = quasi_static(table, dataset.gravity_m_s2)[fresh]
        has_acc = all(c in table.columns for c in ACC)
        acc = table[list(ACC)].to_numpy(float)[fresh] if has_acc else None
        out[recording] = (table[list(MAG)].to_numpy(float)[fresh], acc, static)
    return out


def _ours(samples: np.ndarray, refine_lm: bool = True) -> tuple[np.ndarray, np.ndarray] | str:
    try:
        fit = fit_ellipsoid(samples, refine_lm=refine_lm)
    except ValueError as err:
        return f"refused: {err}"
    return fit.upper, fit.bias


def run_magcal(python: Path, samples: np.ndarray, work: Path, adapter: Path, env: dict) -> dict:
    work.mkdir(parents=True, exist_ok=True)
    data = work / "magcal_input.json"
    data.write_text(json.dumps(samples.tolist()))
    out = work / "magcal_output.json"
    subprocess.run([str(python), str(adapter), str(data), str(out)], check=True, env=env, cwd=work)
    return json.loads(out.read_text())


def fold_figures(recordings: dict, fit_on: int, fitted: dict) -> dict:
    """Held-out figures of each method (``fitted``: name -> (matrix, centre) or a refusal) on
    the runs of parity ``1 - fit_on`` of every recording."""
    out = {}
    for method, model in fitted.items():
        if isinstance(model, str):
            out[method] = {"refused": model}
            continue
        matrix, centre = model
        fields, accs = [], []
        for mag, acc, static in recordings.values():
            held = runs_of(len(mag)) % 2 != fit_on
            cal = (mag[held] - centre) @ np.asarray(matrix).T
            fields.append(cal)
            if acc is not None:
                keep = static[held]
                accs.append((cal[keep], acc[held][keep]))
        entry = norm_figures(np.vstack(fields))
        pairs = [(f, a) for f, a in accs if len(f) > 2]
        if pairs:
            entry["dip_spread_deg"] = dip_spread_deg(
                np.vstack([f for f, _ in pairs]), np.vstack([a for _, a in pairs])
            )
            entry["static_samples"] = int(sum(len(f) for f, _ in pairs))
        out[method] = entry
    return out


def mag_benchmark(name: str, repo: Path, ingest: Callable, run_peer: Callable) -> dict:
    """Both folds of one dataset: each method fitted on one parity of runs, scored on the other."""
    recordings = recordings_with_mag(name, repo, ingest)
    folds = []
    for fit_on in (0, 1):
        samples = np.vstack([m[runs_of(len(m)) % 2 == fit_on] for m, _, _ in recordings.values()])
        peer = run_peer(samples, fit_on)
        fitted = {"raw": (np.eye(3), np.zeros(3)), "magcal": peer.get("refused") or (
            np.asarray(peer["transform_matrix"]), np.asarray(peer["center"]))}  # fmt: skip
        for method, refine in (("ours", True), ("ours, algebraic only", False)):
            ours = _ours(samples, refine)
            if isinstance(ours, str):
                fitted[method] = ours
            else:
                upper, bias = ours
                fitted[method] = (np.real(sqrtm(upper.T @ upper)), bias)
        folds.append({"fit_samples": len(samples), **fold_figures(recordings, fit_on, fitted)})
    return {
        "dataset": name,
        "label": DATASETS[name][0],
        "recordings": {k: len(m) for k, (m, _, _) in recordings.items()},
        "folds": folds,
    }


def table(results: list[dict]) -> str:
    """Markdown: per dataset and method, the held-out figures of both folds."""
    lines = [
        "| recording | fit samples (fold 1 / 2) | method | abs(m)-1 RMS | std/mean of abs(m) "
        "| dip spread, deg (quasi-static samples) |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        n = " / ".join(str(f["fit_samples"]) for f in r["folds"])
        for method in ("raw", "ours", "ours, algebraic only", "magcal"):
            entries = [f[method] for f in r["folds"]]
            if any("refused" in e for e in entries):
                why = next(e["refused"] for e in entries if "refused" in e)
                lines.append(f"| {r['label']} | {n} | {method} | {_short(why)} | | |")
                continue
            dip = [e.get("dip_spread_deg") for e in entries]
            dip_text = (" / ".join(f"{v:.2f}" for v in dip) + f" ({entries[0]['static_samples']})"
                        if all(v is not None for v in dip) else "no accelerometer")  # fmt: skip
            lines.append(
                f"| {r['label']} | {n} | {method} | "
                + " / ".join(f"{e['norm_rms']:.4f}" for e in entries)
                + " | "
                + " / ".join(f"{e['spread']:.4f}" for e in entries)
                + f" | {dip_text} |"
            )
    return "\n".join(lines)


def _short(text: str, limit: int = 110) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."
