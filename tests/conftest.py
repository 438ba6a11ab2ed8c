"""Shared fixtures: where the shared folder (paper, conformance session, real data) lives, and
a dataset's module recordings ingested in memory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
CONFORMANCE = SHARED / "data" / "conformance" / "clean"


@pytest.fixture(scope="session")
def conformance_dir() -> Path:
    """The independent conformance session, or skip when ../shared is not beside the repo."""
    if not (CONFORMANCE / "dataset.yaml").is_file():
        pytest.skip(f"conformance session not found at {CONFORMANCE} (../shared is absent)")
    return CONFORMANCE


def rms_z_limits(n: int, false_alarm: float = 1e-4) -> tuple[float, float]:
    """Central interval of the RMS of ``n`` independent standard normal z-scores.

    ``n * RMS^2`` is chi-square with ``n`` degrees of freedom when the reported standard
    deviations are right; the interval holds it with probability ``1 - false_alarm``. A std off
    by a factor ``f`` moves the RMS to about ``1 / f``.
    """
    from scipy import stats

    low, high = stats.chi2.ppf([false_alarm / 2, 1 - false_alarm / 2], n)
    return float(np.sqrt(low / n)), float(np.sqrt(high / n))


def z_limit(n: int, false_alarm: float = 1e-4, dof: int | None = None) -> float:
    """How many standard deviations a test of ``n`` errors allows each of them.

    The two-sided Bonferroni bound: each of the ``n`` errors of a test stays within the bound
    with probability ``1 - false_alarm / n``, so all of them with at least ``1 - false_alarm``.
    For a normal error over its std the bound is the normal quantile (3.9 for one error,
    4.4 for nine at 1e-4); for an error over a std estimated with ``dof`` degrees of freedom,
    Student's t.
    """
    from scipy import stats

    tail = false_alarm / (2 * n)
    return float(stats.norm.isf(tail) if dof is None else stats.t.isf(tail, dof))


@pytest.fixture(scope="session")
def z_bound():
    """:func:`z_limit` for the "within N std" checks: N from the test's own false-failure
    budget."""
    return z_limit


def binomial_limits(n: int, p: float, false_alarm: float = 1e-4) -> tuple[int, int]:
    """Central interval of the count of ``n`` independent events of probability ``p``.

    Holds a Binomial(n, p) count with probability at least ``1 - false_alarm`` (the
    ``false_alarm / 2`` and ``1 - false_alarm / 2`` quantiles): a decision rule's false alarms
    on data without the thing, or its detections on data with it, must fall inside.
    """
    from scipy import stats

    low, high = stats.binom.ppf([false_alarm / 2, 1 - false_alarm / 2], n, p)
    return int(low), int(high)


@pytest.fixture(scope="session")
def binomial_band():
    """:func:`binomial_limits` for the false-alarm and power checks of decision rules."""
    return binomial_limits


@pytest.fixture(scope="session")
def rms_z_band():
    """:func:`rms_z_limits` for the multi-seed checks of reported standard deviations."""
    return rms_z_limits


def _ingest_imu(dataset) -> dict:
    """Every module recording of a dataset (the reference left out), ingested in memory, by
    name."""
    from imucal.ingest import ingest_recording

    return {
        name: ingest_recording(path, recording=name, dataset=dataset, imucal_version="test")[0]
        for name, path in dataset.recordings.items()
        if name != "reference"
    }


@pytest.fixture(scope="session")
def ingest_imu():
    """``ingest_imu(dataset) -> {name: table}``: the module recordings, as the workflow's
    ingest gives them."""
    return _ingest_imu


def si_options(gravity_m_s2: float = 9.81, *, ranges: dict | None = None):
    """The pipeline's options for SI recordings held in memory (no dataset.yaml: no sensitivity
    nor raw counts; a sensor's range only where ``ranges`` gives it, else nothing is clipped);
    every other setting the schema's default."""
    from imucal.pipeline.options import PipelineOptions

    return PipelineOptions(gravity_m_s2, {}, {}, None, ranges=dict(ranges or {}))


def partial_session(
    tables: dict,
    segments,
    gravity_m_s2: float = 9.81,
    *,
    ranges: dict | None = None,
    **keywords,
):
    """A partial session of SI recordings held in memory with :func:`si_options`.
    ``keywords``: ``notes``, ``references``, ``reference_where`` of
    :class:`imucal.pipeline.partial.Session`."""
    from imucal.pipeline.partial import Session

    return Session(tables, segments, si_options(gravity_m_s2, ranges=ranges), **keywords)
