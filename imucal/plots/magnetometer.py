"""Figures of the magnetometer calibration, as the paper's Figs. 4-7 (return Figures, never save).

* :func:`plot_field` -- the field in 3-D and its components and norm over time: raw (Fig. 4) or
  after step 1 (Fig. 5).
* :func:`plot_phases` -- components and norm per rotation3d phase, optionally with the points the
  paper's step 2 uses (Fig. 6) or after step 2, the constant component highlighted (Fig. 7).
* :func:`plot_magnetometer_steps` -- the four figures from an ingested rotation3d recording, its
  segments and the ``mag.json`` artifact.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from imucal.columns import AXES
from imucal.fits.alignment import phase_samples
from imucal.fits.magnetometer import EllipsoidFit, field_samples
from imucal.plots.style import PAGE_WIDTH_IN

COLOURS = {"x": "tab:red", "y": "tab:green", "z": "tab:blue"}


def plot_field(t_s: np.ndarray, field: np.ndarray, title: str, norm: float | None = None) -> Figure:
    """Field vectors in 3-D (left) and components and norm over time (right).

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Timestamps in s.
    field : ndarray, shape (n, 3)
        Magnetometer values (normalised unit).
    title : str
    norm : float, optional
        Expected norm, drawn as a wire sphere and a line (after step 1).

    Returns
    -------
    Figure
    """
    fig = Figure(figsize=(PAGE_WIDTH_IN, 4.3), layout="constrained")
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax3.scatter(*field.T, s=3, c=t_s, cmap="viridis")
    if norm is not None:
        u, v = np.mgrid[0 : 2 * np.pi : 24j, 0 : np.pi : 12j]
        ax3.plot_wireframe(
            norm * np.cos(u) * np.sin(v),
            norm * np.sin(u) * np.sin(v),
            norm * np.cos(v),
            color="0.7",
            linewidth=0.4,
        )
    ax3.set_xlabel("x")
    ax3.set_ylabel("y")
    ax3.set_zlabel("z")
    ax = fig.add_subplot(1, 2, 2)
    for i, axis in enumerate(AXES):
        ax.plot(t_s, field[:, i], ".", ms=2, color=COLOURS[axis], label=f"m_{axis}")
    ax.plot(t_s, np.linalg.norm(field, axis=1), ".", ms=2, color="k", label="|m|")
    if norm is not None:
        ax.axhline(norm, color="0.5", linewidth=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("field (normalised)")
    ax.legend(loc="lower right", ncols=4, fontsize="small")
    fig.suptitle(title)
    return fig


def plot_phases(
    phases: Mapping[str, tuple[np.ndarray, np.ndarray]],
    title: str,
    used_points: Mapping[str, np.ndarray] | None = None,
) -> Figure:
    """Components and norm of the field in each rotation3d phase.

    Parameters
    ----------
    phases : dict of str to (ndarray (n_i,), ndarray (n_i, 3))
        Phase label -> (timestamps in s, field after step 1 or step 2).
    title : str
    used_points : dict of str to ndarray of int, optional
        Per phase, indices of the points the paper's step 2 used (max/min of the rotating
        components, eqs. 25-27), marked with black crosses as in the paper's Fig. 6.

    Returns
    -------
    Figure
    """
    labels = [lb for lb in AXES if lb in phases]
    fig = Figure(figsize=(PAGE_WIDTH_IN, 3.8), layout="constrained")
    axes = fig.subplots(1, len(labels), sharey=True, squeeze=False)
    for ax, label in zip(axes[0], labels):
        t, v = phases[label]
        for i, axis in enumerate(AXES):
            width = 2.0 if axis == label else 0.8
            ax.plot(t, v[:, i], color=COLOURS[axis], lw=width, label=f"m_{axis}")
        ax.plot(t, np.linalg.norm(v, axis=1), color="k", lw=0.8, label="|m|")
        if used_points is not None and label in used_points:
            idx = np.asarray(used_points[label], dtype=int)
            for i in range(3):
                ax.plot(t[idx], v[idx, i], "kx", ms=7)
        ax.set_title(f"phase {label}: m_{label} must stay constant", fontsize="medium")
        ax.set_xlabel("time (s)")
    axes[0][0].set_ylabel("field (normalised)")
    axes[0][-1].legend(loc="lower right", fontsize="small")
    fig.suptitle(title)
    return fig


def plot_magnetometer_steps(
    rotation3d: pd.DataFrame, segments: pd.DataFrame, artifact: Mapping
) -> dict[str, Figure]:
    """The four figures of the magnetometer calibration (paper Figs. 4-7).

    Parameters
    ----------
    rotation3d : DataFrame
        Ingested rotation3d recording.
    segments : DataFrame
        Segments table with the phases of the rotation3d recording.
    artifact : dict
        ``MagnetometerCalibration.to_dict()`` (the content of ``mag.json``).

    Returns
    -------
    dict of str to Figure
        Keys 'mag_raw', 'mag_step1', 'mag_phases', 'mag_step2'.
    """
    step1 = EllipsoidFit.from_dict(dict(artifact["step1"]))
    matrix = np.asarray(artifact["calibration"]["matrix"], dtype=float)
    bias = np.asarray(artifact["calibration"]["bias"], dtype=float)
    used = artifact["step2"]["used"]
    t, raw = field_samples(rotation3d)
    phases = phase_samples(rotation3d, segments, "mag")
    paper_points = {k: np.asarray(v) for k, v in artifact["step2"]["paper"]["used_points"].items()}
    return {
        "mag_raw": plot_field(t, raw, "Magnetometer, raw (cf. paper Fig. 4)"),
        "mag_step1": plot_field(
            t, step1.apply(raw), f"After step 1 ({step1.used}; cf. Fig. 5)", step1.field_norm
        ),
        "mag_phases": plot_phases(
            {k: (pt, step1.apply(v)) for k, (pt, v) in phases.items()},
            "Phases after step 1, crosses: points of the paper's step 2 (cf. Fig. 6)",
            paper_points,
        ),
        "mag_step2": plot_phases(
            {k: (pt, (v - bias) @ matrix.T) for k, (pt, v) in phases.items()},
            f"Phases after step 2 ({used}; cf. Fig. 7)",
        ),
    }
