"""Monte-Carlo accuracy of the magnetometer calibration against the Cramer-Rao bound.

Simulates rotation3d sessions (static start, two turns about x of B, a 90-degree yaw, two turns
about y, a yaw, two turns about z; magnetometer at 10 Hz, as the conformance session) with random
truths, optionally a cube recording (12 static positions, 6 faces down and 6 at 45 degrees), and
compares step 1 (SVD vs SVD+LM) and step 2 (paper vs full-phase) with the CRLB from the Fisher
information of the same model: readings ``inv(M) u_k + o + noise`` with ``M = T_R S'``, ``u_k``
on the unit sphere, in phase i on a circle about axis i of B (nuisance: one constant per phase and
one angle per sample), elsewhere a free direction (two nuisance angles per sample, or per static
cube position).

Run from the repository root::

    python tests/benchmarks/mc_magnetometer.py --sessions 60 --seed 1

and paste the printed Markdown table into docs/accuracy-magnetometer.md.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.spatial.transform import Rotation

from imucal import errormodel
from imucal.fits.magnetometer import calibrate_alignment, fit_ellipsoid

RATE_HZ = 10.0
#: Per-axis white noise of the normalised magnetometer; the conformance session's residual RMS
#: of |m'| - 1 is 0.004.
NOISE = 0.004
INCLINATION_DEG = 60.0


def random_truth(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Calibration matrix and bias in the ranges of a hard/soft-iron disturbed magnetometer."""
    scale = rng.uniform(0.9, 1.1, 3)
    xi = rng.uniform(-0.05, 0.05, 3)
    alpha = rng.uniform(-0.03, 0.03, 3)
    return errormodel.compose(scale, xi, alpha), rng.uniform(-0.3, 0.3, 3)


def _axis_rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    rv = np.zeros((angle.size, 3))
    rv[:, axis] = angle
    return Rotation.from_rotvec(rv).as_matrix()


def simulate(rng: np.random.Generator, with_cube: bool) -> dict:
    """Field directions in B (noise-free) and their nuisance structure for one session.

    Returns a dict with 'u' (n, 3) unit field in B, 'group' (n,) of 'x'/'y'/'z' (phase), 't'
    (transition or static) or 'cNN' (cube position), and 'phase_index' {label: indices}.
    """
    inc = np.radians(INCLINATION_DEG)
    heading = rng.uniform(0, 2 * np.pi)
    h = np.array([np.cos(inc) * np.cos(heading), np.cos(inc) * np.sin(heading), -np.sin(inc)])
    dt = 1.0 / RATE_HZ
    u, group = [], []
    yaw = 0.0

    def add(rot_wb: np.ndarray, label: str) -> None:
        u.extend(np.einsum("nji,j->ni", rot_wb, h))  # R_wb^T h
        group.extend([label] * rot_wb.shape[0])

    add(_axis_rotation(2, np.full(int(5 * RATE_HZ), yaw)), "t")
    for axis, label in enumerate("xyz"):
        rate = np.radians(rng.choice([-1, 1]) * rng.uniform(45, 60))
        n = round(4 * np.pi / abs(rate) / dt)  # two turns
        ang = rate * dt * np.arange(n) + rng.uniform(0, 2 * np.pi)
        add(_axis_rotation(2, np.full(n, yaw)) @ _axis_rotation(axis, ang), label)
        if label != "z":  # yaw transition of 90 degrees at 20 deg/s
            steps = np.linspace(yaw, yaw + np.pi / 2, int(4.5 * RATE_HZ))
            add(_axis_rotation(2, steps), "t")
            yaw += np.pi / 2
    if with_cube:
        faces = [
            Rotation.from_rotvec(v)
            for v in (
                [0, 0, 0],
                [np.pi, 0, 0],
                [np.pi / 2, 0, 0],
                [-np.pi / 2, 0, 0],
                [0, np.pi / 2, 0],
                [0, -np.pi / 2, 0],
            )
        ]
        tilt = [
            Rotation.from_rotvec(np.radians(45) * np.array(a))
            for a in ([1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [1, 1, 0], [-1, 1, 0])
        ]
        for k, r in enumerate(faces + [t * faces[k % 6] for k, t in enumerate(tilt)]):
            yaw_k = Rotation.from_rotvec([0, 0, rng.uniform(0, 2 * np.pi)])
            add(np.repeat((yaw_k * r).as_matrix()[None], int(8 * RATE_HZ), axis=0), f"c{k:02d}")
    u = np.array(u)
    group = np.array(group)
    return {
        "u": u,
        "group": group,
        "phase_index": {lb: np.flatnonzero(group == lb) for lb in "xyz"},
    }


def crlb(session: dict, matrix: np.ndarray, noise: float, circles: bool = True) -> dict:
    """CRLB (variances) of bias, matrix entries and alpha for the session's model and noise.

    ``circles=False`` forgets that phase samples lie on circles about the axes (the information
    step 1 uses: every rotation3d sample a free direction); alpha then is not identifiable and
    only the bias bound is returned.
    """
    u, group = session["u"], session["group"]
    if not circles:
        group = np.where(np.isin(group, ["x", "y", "z"]), "t", group)
    n = u.shape[0]
    upper_rot, upper = errormodel.upper_triangular_factor(matrix)
    alpha = Rotation.from_matrix(upper_rot).as_rotvec()
    iu = np.triu_indices(3)
    p0 = np.concatenate([upper[iu], alpha])

    def readings(p: np.ndarray) -> np.ndarray:
        up = np.zeros((3, 3))
        up[iu] = p[:6]
        m = errormodel.rotation_matrix(p[6:]) @ up
        return np.linalg.solve(m, u.T).T

    cols = []
    for i in range(9):  # d readings / d (upper, alpha), central differences
        dp = np.zeros(9)
        dp[i] = 1e-6
        cols.append(((readings(p0 + dp) - readings(p0 - dp)) / 2e-6).ravel())
    for i in range(3):  # d readings / d bias
        e = np.zeros((n, 3))
        e[:, i] = 1.0
        cols.append(e.ravel())
    minv = np.linalg.inv(matrix)
    # phase constant c_i: u = c e_a + rho (cos, sin) in the other two axes
    for lb in "xyz" if circles else ():
        idx = np.flatnonzero(group == lb)
        a = "xyz".index(lb)
        c = u[idx, a].mean()
        rho2 = 1 - c * c
        # d u / d c = e_a + (d rho / d c) / rho * (in-plane part) = e_a - c / rho^2 * in-plane
        du = -c / rho2 * u[idx]
        du[:, a] = 1.0
        col = np.zeros((n, 3))
        col[idx] = du @ minv.T
        cols.append(col.ravel())
    nuis = []
    for k in range(n):  # per-sample angles
        g = group[k]
        if g in ("x", "y", "z"):
            tang = [np.cross(np.eye(3)["xyz".index(g)], u[k])]
        elif g == "t":
            t1 = np.cross(u[k], [0.0, 0.0, 1.0] if abs(u[k, 2]) < 0.9 else [1.0, 0.0, 0.0])
            t1 /= np.linalg.norm(t1)
            tang = [t1, np.cross(u[k], t1)]
        else:
            continue
        for t in tang:
            col = np.zeros((n, 3))
            col[k] = minv @ t
            nuis.append(col.ravel())
    for g in sorted(set(group) - {"x", "y", "z", "t"}):  # cube: two angles per position
        idx = np.flatnonzero(group == g)
        v = u[idx[0]]
        t1 = np.cross(v, [0.0, 0.0, 1.0] if abs(v[2]) < 0.9 else [1.0, 0.0, 0.0])
        t1 /= np.linalg.norm(t1)
        for t in (t1, np.cross(v, t1)):
            col = np.zeros((n, 3))
            col[idx] = minv @ t
            nuis.append(col.ravel())
    if not circles:  # the rotation is not observable: keep the 6 of S' and the bias
        cols = cols[:6] + cols[9:12]
        jac = np.column_stack(cols + nuis)
        return {"bias": np.diag(np.linalg.inv(jac.T @ jac))[6:9] * noise**2}
    jac = np.column_stack(cols + nuis)
    cov = np.linalg.inv(jac.T @ jac) * noise**2
    # matrix entries: M = R(alpha) U
    g = np.empty((9, 9))
    for i in range(9):
        dp = np.zeros(9)
        dp[i] = 1e-6
        up_p, up_m = np.zeros((3, 3)), np.zeros((3, 3))
        up_p[iu], up_m[iu] = (p0 + dp)[:6], (p0 - dp)[:6]
        mp = errormodel.rotation_matrix((p0 + dp)[6:]) @ up_p
        mm = errormodel.rotation_matrix((p0 - dp)[6:]) @ up_m
        g[:, i] = ((mp - mm) / 2e-6).ravel()
    return {
        "bias": np.diag(cov)[9:12],
        "matrix": np.diag(g @ cov[:9, :9] @ g.T),
        "alpha": np.diag(cov)[6:9],
    }


def run(sessions: int, seed: int, noise: float, with_cube: bool) -> dict:
    rng = np.random.default_rng(seed)
    err = {}
    bound = {"bias": [], "matrix": [], "alpha": [], "bias_sphere": []}
    for _ in range(sessions):
        matrix, bias = random_truth(rng)
        s = simulate(rng, with_cube)
        raw = errormodel.invert(matrix, bias, s["u"]) + rng.normal(0, noise, s["u"].shape)
        rot_mask = ~np.char.startswith(s["group"].astype(str), "c")
        phases = {lb: raw[idx] for lb, idx in s["phase_index"].items()}
        extra = {"cube": raw[~rot_mask]} if with_cube else None
        true_alpha = errormodel.decompose(matrix).alpha_rad
        for lm in (False, True):
            fit = fit_ellipsoid(raw[rot_mask], refine_lm=lm, extra_samples=extra)
            for method in ("paper", "full"):
                for exact in (True, False):
                    cal = calibrate_alignment(fit, phases, method=method, exact=exact).calibration
                    key = ("svd+lm" if lm else "svd", method, "exact" if exact else "small-angle")
                    e = err.setdefault(key, {"bias": [], "matrix": [], "alpha": []})
                    e["n"] = e.get("n", 0) + 1
                    e["bias"].append(cal.bias - bias)
                    e["matrix"].append((cal.matrix - matrix).ravel())
                    e["alpha"].append(errormodel.decompose(cal.matrix).alpha_rad - true_alpha)
        b = crlb(s, matrix, noise)
        b["bias_sphere"] = crlb(s, matrix, noise, circles=False)["bias"]
        for k, values in bound.items():
            values.append(b[k])
    crlb_mean = {k: float(np.mean(v)) for k, v in bound.items()}
    rows = {}
    for key, e in err.items():
        # efficiency: squared error over that session's CRLB, averaged (robust to sessions whose
        # geometry is poor), next to the plain mean squared error
        rows[key] = {k: float(np.mean(np.square(e[k]))) for k in ("bias", "matrix", "alpha")}
        rows[key]["eff"] = {
            k: float(
                np.mean(np.square(e[k if k != "bias_sphere" else "bias"]) / np.array(bound[k]))
            )
            for k in bound
        }
    return {"rows": rows, "crlb": crlb_mean}


def table(result: dict, title: str) -> str:
    c = result["crlb"]
    lines = [
        f"**{title}**",
        "",
        (
            "| step 1 | step 2 | T_R form | RMS bias | eff. bias | RMS matrix | eff. matrix "
            "| RMS alpha (deg) | eff. alpha | eff. bias (sphere CRLB) |"
        ),
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for (s1, s2, form), r in sorted(result["rows"].items()):
        lines.append(
            f"| {s1} | {s2} | {form} | {np.sqrt(r['bias']):.2e} | {r['eff']['bias']:.2f} "
            f"| {np.sqrt(r['matrix']):.2e} | {r['eff']['matrix']:.2f} "
            f"| {np.degrees(np.sqrt(r['alpha'])):.4f} | {r['eff']['alpha']:.2f} "
            f"| {r['eff']['bias_sphere']:.2f} |"
        )
    lines.append(
        f"| CRLB | | | {np.sqrt(c['bias']):.2e} | 1 | {np.sqrt(c['matrix']):.2e} | 1 "
        f"| {np.degrees(np.sqrt(c['alpha'])):.4f} | 1 | |"
    )
    lines.append(f"| CRLB sphere only | | | {np.sqrt(c['bias_sphere']):.2e} | | | | | | 1 |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", type=int, default=60)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--noise", type=float, default=NOISE)
    args = parser.parse_args()
    t0 = time.perf_counter()
    for with_cube in (False, True):
        result = run(args.sessions, args.seed, args.noise, with_cube)
        title = (
            f"{'rotation3d + cube' if with_cube else 'rotation3d only'}: "
            f"{args.sessions} sessions, noise {args.noise:g} per axis, seed {args.seed}"
        )
        print(table(result, title))
        print()
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
