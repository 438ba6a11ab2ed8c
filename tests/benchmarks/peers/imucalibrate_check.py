"""The IMUcalibrate port against scikit-diveMove's own code, on the peer's own CATS recording.

scikit-diveMove's docs and tests publish no fitted coefficient of this recording (its test
``test_imucalibrate.py`` asserts three models per variable and the types; its docstring
example prints the dataset summary: 268081 samples, three periods). So the figure to
reproduce is the peer's own output: ``skdivemove_adapter.py`` runs ``build_tmodels`` from the
0.4.0 wheel with the calls of its test, and the port (:mod:`imucalibrate_port`) must give the
same intercepts, slopes and standard errors (and, with ``T_brk``, the pseudo-inverse solution)
to round-off. The package's own IMUcalibrate model of the hold-out
(:func:`imucal.terms.thermalpeers.per_period_line`) must give the port's slope.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
from imucalibrate_port import build_tmodels

#: The peer's periods (its test and docstring) in s since the file's epoch 2021-09-20 08:52:00,
#: both ends included as xarray's label slices include them.
PERIODS_S = [(480, 92460), (92880, 183780), (184920, 268020)]
AXIS_ORDER = "zxy"
VARIABLES = ("acceleration", "angular_velocity", "magnetic_density")


def load_cats(path: Path) -> dict:
    """Per variable the periods' (temperature (n,), signal (n, 3)) of the CATS file."""
    with h5py.File(path, "r") as f:
        t = f["timestamp_utc"][:]
        temp = f["temperature"][:]
        values = {v: f[v][:] for v in VARIABLES}
    out = {}
    for v in VARIABLES:
        out[v] = []
        for a, b in PERIODS_S:
            keep = (t >= a) & (t <= b)
            out[v].append((temp[keep], values[v][keep]))
    return out


def port_models(periods: dict, t_brk: float | None) -> list[dict]:
    """The port's models in the adapter's layout (one entry per variable, period and axis)."""
    rows = []
    for var in VARIABLES:
        use_axis_order = var != "angular_velocity"
        axes = [["xyz".index(a)] for a in AXIS_ORDER] if use_axis_order else None
        for p, models in enumerate(build_tmodels(periods[var], t_brk=t_brk, axes=axes)):
            for j, m in models.items():
                rows.append({
                    "var": var, "period": p, "axis": "xyz"[j], "t_brk": t_brk,
                    "params": m.params.tolist(), "bse": m.bse.tolist(), "nobs": m.nobs,
                    "at_t_alpha": m.at_t_alpha, "t_alpha": m.t_alpha,
                })  # fmt: skip
    return rows


def compare(peer: list[dict], port: list[dict]) -> dict:
    """Largest relative differences of the port from the peer, over all models."""
    key = lambda r: (r["var"], r["period"], r["axis"], r["t_brk"])  # noqa: E731
    ours = {key(r): r for r in port}
    worst = {"params": 0.0, "bse": 0.0, "at_t_alpha": 0.0}
    for r in peer:
        q = ours[key(r)]
        if q["nobs"] != r["nobs"]:
            raise ValueError(f"{key(r)}: {q['nobs']} samples in the port, {r['nobs']} in the peer")
        for name in worst:
            a, b = np.atleast_1d(q[name]), np.atleast_1d(r[name])
            worst[name] = max(worst[name], float(np.max(np.abs(a - b) / np.abs(b))))
    return {"models": len(peer), "max_relative_difference": worst}


def table(result: dict) -> str:
    """Markdown: the port against the peer's own code, and the peer's slopes."""
    worst = result["port_vs_peer"]["max_relative_difference"]
    versions = ", ".join(f"{k} {v}" for k, v in result["peer_versions"].items())
    lines = [
        f"scikit-diveMove's own `build_tmodels` ({versions}) and the port, "
        f"{result['port_vs_peer']['models']} models (accelerometer and magnetometer with "
        "`use_axis_order=True`, the gyroscope on every axis, each without and with `T_brk=10`): "
        f"largest relative difference of the coefficients {worst['params']:.1e}, of their "
        f"standard errors {worst['bse']:.1e}, of the prediction at `T_alpha` "
        f"{worst['at_t_alpha']:.1e}.",
        "",
        "| variable | period | axis | intercept | slope per deg C | its std (OLS) | samples |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in result["peer"]["models"]:
        if m["t_brk"] is None:
            lines.append(
                f"| {m['var']} | {m['period']} | {m['axis']} | {m['params'][0]:.6g} | "
                f"{m['params'][1]:.6g} | {m['bse'][1]:.3g} | {m['nobs']} |"
            )
    return "\n".join(lines)
