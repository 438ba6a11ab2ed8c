"""Known bugs put back one at a time, each against the tests of its module.

Every entry of :data:`BUGS` is an edit of the product's code that the confidence tests exist
to catch (docs/testing.md, "Bugs the tests are known to catch"): a wrong degree of freedom in
a reported std, a covariance carried through a matrix instead of its transpose, windows that
share a sample, the one-standard-error rule without its sqrt(n), Holm's step with the wrong
rank, the detection score without its prediction-interval factor, a verdict read with another
parameter's std, a clipping margin moved by one count. Each is made in a scratch copy (never in
the checkout), the tests named with it run (``slow`` ones left out) and the first failing test
is printed; a bug they do not fail is an escape and the command exits non-zero.

Usage (from the repository root)::

    python tests/mutation/seeded.py            # all of them
    python tests/mutation/seeded.py dof        # those whose name holds "dof"
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run import scratch_copy  # noqa: E402

#: (name, module, the code as it is, the bug, the tests that must fail on it).
BUGS = [
    # wrong degrees of freedom of a reported std (or its sqrt)
    (
        "dof cube noise",
        "imucal/fits/accelerometer.py",
        "dof = sum(len(p) - 1 for p in positions)",
        "dof = sum(len(p) for p in positions)",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "dof known orientations",
        "imucal/fits/ferraris.py",
        "dof = 3 * (n_pos - MIN_POSITIONS)",
        "dof = 3 * n_pos - MIN_POSITIONS",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "dof pose to pose",
        "imucal/fits/posetopose.py",
        "dof = 2 * n - 9",
        "dof = 2 * n - 6",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "dof rate table",
        "imucal/fits/ratetable.py",
        "dof = len(w) - 4",
        "dof = len(w) - 3",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "dof ellipsoid",
        "imucal/fits/magnetometer.py",
        "dof = m.shape[0] - p.size",
        "dof = m.shape[0]",
        ["tests/fits/test_magnetometer.py"],
    ),
    (
        "dof reference fit",
        "imucal/fits/reference.py",
        "dof = max(res.size - n_free, 1)",
        "dof = max(res.size - 3 * n_free, 1)",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "dof reference jackknife",
        "imucal/fits/reference.py",
        "return formal, (N_BLOCKS - 1) / N_BLOCKS * centred.T @ centred",
        "return formal, N_BLOCKS / (N_BLOCKS - 1) * centred.T @ centred",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "dof gyro bias noise",
        "imucal/fits/gyroscope.py",
        "diff_n = sum(len(s) - 1 for s in segments)",
        "diff_n = sum(len(s) for s in segments)",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "dof alignment",
        "imucal/fits/alignment.py",
        "dof = r.size - 3 - n_nuisance",
        "dof = r.size - 3",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "dof time offset",
        "imucal/validation/timing.py",
        "dof = max(sol.fun.size - int(free.sum()), 1)",
        "dof = max(sol.fun.size, 1)",
        ["tests/validation/test_timing_exact.py"],
    ),
    (
        "dof time offset windows (Birge)",
        "imucal/validation/timing.py",
        "/ (win_t_a.size - 2)",
        "/ (win_t_a.size - 1)",
        ["tests/validation/test_timing_exact.py"],
    ),
    (
        "dof block standard error",
        "imucal/terms/blockspread.py",
        "return m, np.sqrt(b / (b - 1) * np.sum",
        "return m, np.sqrt(np.sum",
        ["tests/terms/test_order_rules.py"],
    ),
    (
        "dof ratio interval (Satterthwaite)",
        "imucal/terms/blockspread.py",
        "return blocks / (blocks - 1) * float(np.sum(phi**2)), blocks - 1",
        "return blocks / (blocks - 1) * float(np.sum(phi**2)), blocks",
        ["tests/terms/test_order_rules.py"],
    ),
    (
        "sqrt mean std of the bias",
        "imucal/fits/gyroscope.py",
        "std_mean_rad_s=noise / np.sqrt(n),",
        "std_mean_rad_s=noise / n,",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "dof tool-free pause variance",
        "imucal/pipeline/stages/toolfree.py",
        "var = float(np.var(offset, ddof=1)) / len(v)",
        "var = float(np.var(offset)) / len(v)",
        ["tests/pipeline/test_uncertainty_chain.py"],
    ),
    # a covariance carried through a matrix instead of its transpose
    (
        "transpose delta method",
        "imucal/uncertainty.py",
        "out = jac @ np.asarray(covariance, dtype=float) @ jac.T",
        "out = jac @ np.asarray(covariance, dtype=float) @ jac",
        ["tests/test_uncertainty.py"],
    ),
    (
        "transpose rate table K from K^-1",
        "imucal/fits/ratetable.py",
        'jac[:9, :9] = -np.einsum("ia,bj->ijab", matrix, matrix)',
        'jac[:9, :9] = -np.einsum("ia,bj->ijab", matrix.T, matrix)',
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "transpose rate table QR factor",
        "imucal/fits/ratetable.py",
        "cov_upper = j_upper @ covariance[:9, :9] @ j_upper.T",
        "cov_upper = j_upper.T @ covariance[:9, :9] @ j_upper",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "transpose magnetometer alignment",
        "imucal/fits/reference.py",
        "covariance = to_alpha @ small @ to_alpha.T",
        "covariance = to_alpha.T @ small @ to_alpha",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "transpose pose-to-pose matrix",
        "imucal/fits/posetopose.py",
        '"matrix": np.sqrt(np.clip(np.diag(jm @ cov @ jm.T), 0, None)).reshape(3, 3),',
        '"matrix": np.sqrt(np.clip(np.diag(jm.T @ cov @ jm), 0, None)).reshape(3, 3),',
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "transpose pose-to-pose matrix with the bias",
        "imucal/fits/posetopose.py",
        "cov_b, jm @ cov @ jm.T + to_matrix @ cov_b @ to_matrix.T, to_matrix @ cov_b",
        "cov_b, jm.T @ cov @ jm + to_matrix @ cov_b @ to_matrix.T, to_matrix @ cov_b",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "transpose cube residual weights",
        "imucal/fits/accelerometer.py",
        "return weight * (np.linalg.norm((v - bias) @ upper.T, axis=1) - target)",
        "return weight * (np.linalg.norm((v - bias) @ upper, axis=1) - target)",
        ["tests/fits/test_std_exact.py"],
    ),
    # windows that share a sample
    (
        "window reference fit",
        "imucal/fits/reference.py",
        "        j = k + 1\n",
        "        j = k\n",
        ["tests/fits/test_std_exact.py"],
    ),
    (
        "window comparison",
        "imucal/validation/orientation.py",
        "if start >= last + window_s:",
        "if start >= last + window_s / 2:",
        ["tests/validation/test_decision_rates.py"],
    ),
    # the one-standard-error rule without its sqrt(n)
    (
        "one-se sqrt(n) temperature order",
        "imucal/gap/temperature.py",
        "finite[best].std(ddof=1) / np.sqrt(len(y))",
        "finite[best].std(ddof=1)",
        ["tests/gap/test_decision_rules.py"],
    ),
    (
        "one-se block error across poses",
        "imucal/terms/blockspread.py",
        "np.sum((sums - m * counts) ** 2)) / n",
        "np.sum((sums - m * counts) ** 2)) / np.sqrt(n)",
        ["tests/terms/test_order_rules.py"],
    ),
    (
        "one-se rule bound",
        "imucal/terms/poseholdout.py",
        "if pooled[k][0] <= sum(pooled[best])",
        "if pooled[k][0] <= pooled[best][0]",
        ["tests/terms/test_order_rules.py"],
    ),
    # Holm's step with the wrong rank
    (
        "holm rank",
        "imucal/gap/null.py",
        "if p[i] > alpha / (m - rank):",
        "if p[i] > alpha / (m - rank + 1):",
        ["tests/gap/test_decision_rules.py"],
    ),
    # the detection score without its prediction-interval factor
    (
        "detection z factor",
        "imucal/gap/attribution.py",
        "spread = np.std(vals, ddof=1) * np.sqrt(1 + 1 / len(vals))",
        "spread = np.std(vals, ddof=1)",
        ["tests/gap/test_decision_rules.py"],
    ),
    (
        "detection z given factor",
        "imucal/gap/attribution.py",
        "var = np.var(vals, ddof=1) * (1 + 1 / len(vals))",
        "var = np.var(vals, ddof=1)",
        ["tests/gap/test_decision_rules.py"],
    ),
    # a verdict read with another parameter's std
    (
        "plausibility angle std",
        "imucal/validation/plausibility.py",
        "std[1, 2], std[0, 2], std[0, 1]",
        "std[0, 2], std[1, 2], std[0, 1]",
        ["tests/validation/test_decision_rates.py"],
    ),
    (
        "plausibility scale std",
        "imucal/validation/plausibility.py",
        "std_scale = np.abs(np.diag(std))",
        "std_scale = np.abs(np.diag(std))[[1, 0, 2]]",
        ["tests/validation/test_decision_rates.py"],
    ),
    # a clipping margin moved by one count
    (
        "clip count at the top",
        "imucal/ingest/checks.py",
        "pc.equal(values, hi)",
        "pc.equal(values, hi - 1)",
        ["tests/ingest/test_clipping_margins.py"],
    ),
    (
        "clip count at the bottom",
        "imucal/ingest/checks.py",
        "pc.equal(values, lo)",
        "pc.equal(values, lo + 1)",
        ["tests/ingest/test_clipping_margins.py"],
    ),
    (
        "clip count beyond",
        "imucal/ingest/checks.py",
        "pc.greater(values, hi)",
        "pc.greater(values, hi - 1)",
        ["tests/ingest/test_clipping_margins.py"],
    ),
    (
        "clip SI range",
        "imucal/pipeline/stages/common.py",
        "np.abs(values) >= limit",
        "np.abs(values) > limit",
        ["tests/ingest/test_clipping_margins.py"],
    ),
    (
        "clip cube fit",
        "imucal/fits/accelerometer.py",
        "limit_m_s2 * (1 - 1e-9)",
        "limit_m_s2 * (1 - 1e-4)",
        ["tests/ingest/test_clipping_margins.py"],
    ),
    (
        "clip extreme half step",
        "imucal/segments/detector.py",
        "<= step / 2",
        "<= step * 1.5",
        ["tests/ingest/test_clipping_margins.py"],
    ),
    (
        "clip motion count",
        "imucal/segments/detector.py",
        "at_extreme(x[:, k], a, b, sign).sum() >= enough",
        "at_extreme(x[:, k], a, b, sign).sum() > enough",
        ["tests/ingest/test_clipping_margins.py"],
    ),
    # thresholds of rest detection and of the plausibility verdict
    (
        "rest threshold quantile",
        "imucal/segments/detector.py",
        "limit = special.chdtri(dof, p_false) / dof",
        "limit = special.chdtri(dof, p_false / 10) / dof",
        ["tests/segments/test_detector_rates.py"],
    ),
    (
        "plausibility boundary",
        "imucal/validation/plausibility.py",
        "if outside > CONFIDENT_SIGMA * std:",
        "if outside >= CONFIDENT_SIGMA * std:",
        ["tests/validation/test_decision_rates.py"],
    ),
]


def main(argv: list[str]) -> int:
    wanted = [b for b in BUGS if not argv or any(a in b[0] for a in argv)]
    root = scratch_copy(None)
    env = dict(os.environ, PYTHONPATH=str(root), OPENBLAS_NUM_THREADS="1",
               PYTHONDONTWRITEBYTECODE="1")  # fmt: skip
    escaped = []
    for name, path, old, new, extra in wanted:
        target = root / path
        source = target.read_text()
        if source.count(old) != 1:
            raise SystemExit(f"{name}: {old!r} is not once in {path}")
        tests = extra
        target.write_text(source.replace(old, new))
        start = time.monotonic()
        try:
            done = subprocess.run(
                [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider",
                 "-m", "not slow", *tests],
                cwd=root, env=env, capture_output=True, text=True,
            )  # fmt: skip
        finally:
            target.write_text(source)
        failed = re.findall(r"^FAILED (\S+)", done.stdout, flags=re.M)
        verdict = f"caught by {failed[0]}" if failed else f"ESCAPED (exit {done.returncode})"
        if not failed:
            escaped.append(name)
        print(f"{name}: {verdict} ({time.monotonic() - start:.0f} s)", flush=True)
    print(f"{len(wanted) - len(escaped)} of {len(wanted)} caught; escaped: {escaped}")
    return 1 if escaped else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
