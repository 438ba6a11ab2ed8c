"""Effects real parts have that the gap diagnosis's library does not hold: the simulator only.

The diagnosis (:mod:`imucal.gap`) knows the effects of :data:`imucal.sim.effects.EFFECTS` and
has, for each, an estimator or the reason it cannot see it. The effects here are outside that
library on purpose: they render sessions on which the right verdict is "the twin lacks an
effect the library does not hold, at these locations", never a library effect that fits by
flexibility. No module of the diagnosis imports this package (``tests/gap/test_outside.py``
holds it so); the checks that render hidden sessions do (:mod:`imucal.gap.outside`).

They keep the simulator's effect interface (:class:`imucal.sim.effects.Effect`: hooks, realistic
defaults, :meth:`~imucal.sim.effects.Effect.magnitude`, :meth:`~imucal.sim.effects.Effect.scaled`)
and have a registry of their own (:data:`OUTSIDE`), so that the library's contract, which walks
every registered effect of the simulator, does not ask the diagnosis for them.

========================  ==========================================================  ==========
effect                    what (realistic size)                                       hook
========================  ==========================================================  ==========
``rate_sign_scale``       the gyroscope's scale differs for positive and negative      readings
                          rates (0.3 % between the signs)
``bias_step``             a bias that jumps part-way through the session (gyro          readings
                          0.1 deg/s)
``acc_sign_scale``        the accelerometer's scale differs for positive and            readings
                          negative force (0.4 % between the signs)
``g2_sensitivity``        the gyroscope reads the square of the specific force          readings
                          (0.01 deg/s/g^2)
``acc_cross_product``     an accelerometer axis reads the product of the other two      readings
                          (1 mg at a cube edge)
``output_filter``         a digital low-pass filter on acc and gyro (20 Hz, the         readings
                          MPU class's DLPF), noise included
========================  ==========================================================  ==========
"""

from imucal.sim.outside.base import OUTSIDE, make_outside, register_outside
from imucal.sim.outside.sensor import (
    AccCrossProduct,
    AccSignScale,
    BiasStep,
    G2Sensitivity,
    RateSignScale,
)
from imucal.sim.outside.timing import OutputFilter

__all__ = [
    "OUTSIDE",
    "AccCrossProduct",
    "AccSignScale",
    "BiasStep",
    "G2Sensitivity",
    "OutputFilter",
    "RateSignScale",
    "make_outside",
    "register_outside",
]
