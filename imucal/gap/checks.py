"""The simulated checks of the diagnosis (blind, stress, detection): one way to score a run.

Each check renders sessions with sealed answer keys, diagnoses them without the keys, and is
scored by its own function once every diagnosis is done; :func:`score_check` unseals the keys,
scores, adds the diagnosis run times and renders the check's page.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from imucal.gap.blind import score_blind
from imucal.gap.detection import score_detection
from imucal.gap.figures import render_blind_page, render_detection_page
from imucal.gap.stress import render_stress_page, score_stress
from imucal.io import read_benchmark_seconds, read_json

#: Check -> (scoring function of (diagnoses, keys, **options), page renderer of the score).
CHECKS = {
    "blind": (score_blind, render_blind_page),
    "stress": (score_stress, render_stress_page),
    "detection": (score_detection, render_detection_page),
}


def score_check(
    check: str,
    diagnoses: Sequence[str | Path],
    sealed: Sequence[str | Path],
    benchmarks: Sequence[str | Path],
    **options,
) -> tuple[dict, str]:
    """Score one check's run.

    Parameters
    ----------
    check : {'blind', 'stress', 'detection'}
    diagnoses, sealed, benchmarks : sequence of path
        The diagnosis JSONs, the answer keys (both named by session) and the diagnose rule's
        Snakemake benchmark files.
    **options
        Passed to the check's scoring function (detection: ``rate``, ``confidence``).

    Returns
    -------
    score : dict
        The check's score plus ``diagnosis_seconds``.
    page : str
        The check's self-contained HTML page.
    """
    if check not in CHECKS:
        raise ValueError(f"check {check!r}: expected one of {sorted(CHECKS)}")
    score_fn, render = CHECKS[check]
    by_session = {Path(f).stem: read_json(f) for f in diagnoses}
    keys = {Path(f).stem: read_json(f) for f in sealed}
    score = score_fn(by_session, keys, **options)
    score["diagnosis_seconds"] = read_benchmark_seconds(benchmarks)
    return score, render(score)
