"""Physics gates of the library's effects, by their false-alarm rate and power on synthetic
estimates of known truth: a placement error tilts gravity and the field together."""

from __future__ import annotations

import numpy as np
from scipy import stats as sps

from imucal.gap.effects import Estimate
from imucal.gap.library.mounting import TOGETHER_P, placement_gate


def _band(n: int, p: float, budget: float = 1e-3) -> int:
    """The largest count of ``n`` draws at rate ``p`` that passes with ``budget``."""
    return int(sps.binom.isf(budget, n, p))


def _tilts(rng, placement: float, acc_only: float, noise: float = 1e-3, n: int = 12):
    """Per cube position the accelerometer's and the field's tilts (rad): a rigid turn of std
    ``placement`` in both, an error of the accelerometer alone of std ``acc_only``, and each
    sensor's own noise."""
    turn = rng.normal(0, placement, n)
    acc = turn + rng.normal(0, acc_only, n) + rng.normal(0, noise, n)
    field = turn + rng.normal(0, noise, n)
    return Estimate({}, 0.0, {"acc_tilt": acc, "field_tilt": field, "free": np.full(n, 0.7)})


def test_a_rigid_turn_passes_the_gate():
    rng = np.random.default_rng(1)
    n = 200
    refused = sum(bool(placement_gate(_tilts(rng, 5e-3, 0.0), [], 4.0)) for _ in range(n))
    assert refused <= _band(n, 0.02), refused  # power >= 98 % at 5 noise std


def test_an_accelerometer_error_alone_is_not_a_placement():
    """False alarm: tilts of the accelerometer alone, ten times its noise, pass the gate at its
    level (the correlation under independence is Student's t)."""
    rng = np.random.default_rng(2)
    n = 400
    passed = sum(not placement_gate(_tilts(rng, 0.0, 1e-2), [], 4.0) for _ in range(n))
    assert passed <= _band(n, TOGETHER_P), passed
    reasons = [placement_gate(_tilts(rng, 0.0, 1e-2), [], 4.0) for _ in range(5)]
    assert any(
        r.startswith("the accelerometer's tilts and the field's do not move") for r in reasons
    )
