"""A short module recording inside a long reference: the offset is found from the overlap."""

from __future__ import annotations

import numpy as np

from imucal.validation.timing import estimate_time_alignment


def _rates(t: np.ndarray, phases: np.ndarray) -> np.ndarray:
    """Body rates (n, 3), rad/s: a few sines of 0.2 to 1.5 Hz per axis, no period in common."""
    freqs = np.array([0.23, 0.61, 1.07, 1.49])
    return np.stack(
        [np.sin(2 * np.pi * freqs[None, :] * t[:, None] + phases[k]).sum(axis=1) for k in range(3)],
        axis=1,
    )


def test_a_module_recording_a_third_of_the_references_length_is_aligned(z_bound):
    """The module records 20 s in the middle of a 70 s reference, its clock 31.25 s behind:
    the overlap is the whole module recording, under half of the reference, and the offset is
    found within its std (the cross-correlation's search asks the overlap for half of the
    shorter recording, not of the longer)."""
    rng = np.random.default_rng(5)
    phases = rng.uniform(0, 2 * np.pi, (3, 4))
    offset = 31.25
    t_r = np.arange(0.0, 70.0, 0.01)
    t_m = np.arange(0.0, 20.0, 0.005)
    gyr_r = _rates(t_r, phases) + rng.normal(0.0, 0.01, (t_r.size, 3))
    gyr_m = _rates(t_m + offset, phases) + rng.normal(0.0, 0.01, (t_m.size, 3))
    fit = estimate_time_alignment(t_m, gyr_m, t_r, gyr_r)
    assert abs(fit.offset_s - offset) <= z_bound(1) * fit.offset_std_s
    assert fit.offset_std_s < 1e-3
