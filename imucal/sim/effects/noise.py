"""Effects on the sensor noise beyond white noise: bias_instability."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.signal import lfilter

from imucal.columns import SENSORS
from imucal.sim.effects.base import Effect, Magnitude, RecordingContext, register, stream_rng
from imucal.sim.motion import KinematicState
from imucal.sim.sensors import Signals


@register
@dataclass(frozen=True)
class BiasInstability(Effect):
    """Slowly wandering biases: random walk plus first-order Gauss-Markov, per sensor and axis.

    The bias of each of the nine channels (3 sensors x 3 axes, sensor frame, added to the
    reading) is ``b(t) = w(t) + g(t)`` on the *session clock* (recordings follow one another,
    so the process is continuous across recordings and through the gaps between them):

    * ``w``: random walk from 0 at the session start, ``w(t + dt) = w(t) + rw sqrt(dt) n``
      (rate random walk for the gyroscope, IEEE 952 Allan slope +1/2);
    * ``g``: stationary first-order Gauss-Markov process with std ``gm`` and correlation time
      ``tau_s``, ``g(t + dt) = exp(-dt / tau) g(t) + gm sqrt(1 - exp(-2 dt / tau)) n``, a common
      stand-in for the flicker (bias instability) floor: its Allan deviation is flat-topped
      near ``tau`` with a peak of about ``0.62 gm``. It has zero mean, so the truth's bias is
      its long-run value.

    The process is drawn on a grid of the packet period from the session start, from one
    random stream of the seed, and interpolated linearly to the samples of each recording, so
    every recording sees the same realisation. ``truth.json["effects_realised"]`` gets the
    mean bias of each recording per sensor (SI, sensor frame), what a per-recording bias
    estimate should find.

    Parameters
    ----------
    acc_rw, gyr_rw, mag_rw : float
        Random-walk coefficients, >= 0: m/s^2/sqrt(s), rad/s/sqrt(s), normalised/sqrt(s).
    acc_gm, gyr_gm, mag_gm : float
        Gauss-Markov standard deviations, >= 0: m/s^2, rad/s, normalised.
    acc_tau_s, gyr_tau_s, mag_tau_s : float
        Gauss-Markov correlation times (s), > 0.

    Notes
    -----
    Realistic (MEMS class, effects.md #3): gyro bias instability 10-30 deg/h -> ``gyr_gm``
    1e-4 rad/s (20 deg/h), rate random walk ``gyr_rw`` 2e-6 rad/s/sqrt(s) (about
    25 deg/h/sqrt(h)); accelerometer bias instability 0.05-0.1 mg -> ``acc_gm`` 5e-4 m/s^2,
    ``acc_rw`` 2e-5 m/s^2/sqrt(s); correlation times 100 s; the magnetometer has none.
    """

    name = "bias_instability"
    scalable = ("acc_rw", "gyr_rw", "mag_rw", "acc_gm", "gyr_gm", "mag_gm")
    #: Horizon of :meth:`magnitude` (s).
    HORIZON_S: ClassVar[float] = 1000.0
    acc_rw: float = 2e-5
    gyr_rw: float = 2e-6
    mag_rw: float = 0.0
    acc_gm: float = 5e-4
    gyr_gm: float = 1e-4
    mag_gm: float = 0.0
    acc_tau_s: float = 100.0
    gyr_tau_s: float = 100.0
    mag_tau_s: float = 100.0

    def __post_init__(self) -> None:
        for s in SENSORS:
            for kind in ("rw", "gm"):
                value = getattr(self, f"{s}_{kind}")
                if not value >= 0:
                    raise ValueError(f"bias_instability {s}_{kind} must be >= 0, got {value}")
            tau = getattr(self, f"{s}_tau_s")
            if not tau > 0:
                raise ValueError(f"bias_instability {s}_tau_s must be > 0 s, got {tau}")

    def bias(self, t_s: np.ndarray, rate_hz: float, seed: int) -> dict:
        """The bias of each sensor at session times ``t_s``.

        Parameters
        ----------
        t_s : ndarray, shape (n,)
            Session times (s), >= 0.
        rate_hz : float
            Rate of the grid the process is drawn on (the packet rate).
        seed : int
            The session's seed.

        Returns
        -------
        dict
            Sensor -> ndarray, shape (n, 3), SI units.
        """
        t = np.asarray(t_s, dtype=float)
        dt = 1.0 / rate_hz
        n_grid = int(np.ceil(t.max() / dt)) + 2
        grid = np.arange(n_grid) * dt
        # one stream for the session; rows are drawn in time order, so a longer grid extends
        # the same realisation (each recording draws up to its own end)
        draws = stream_rng(seed, f"effect/{self.name}").standard_normal((n_grid, 18))
        out = {}
        for i, s in enumerate(SENSORS):
            e_rw = draws[:, 6 * i : 6 * i + 3]
            e_gm = draws[:, 6 * i + 3 : 6 * i + 6]
            rw, gm, tau = (getattr(self, f"{s}_{k}") for k in ("rw", "gm", "tau_s"))
            walk = np.vstack([np.zeros((1, 3)), np.cumsum(e_rw[1:], axis=0) * rw * np.sqrt(dt)])
            a = np.exp(-dt / tau)
            g0 = gm * e_gm[0]
            markov = np.empty((n_grid, 3))
            markov[0] = g0
            markov[1:] = lfilter(
                [gm * np.sqrt(1 - a**2)], [1.0, -a], e_gm[1:], axis=0, zi=(a * g0)[None, :]
            )[0]
            b = walk + markov
            out[s] = np.column_stack([np.interp(t, grid, b[:, j]) for j in range(3)])
        return out

    def on_readings(
        self, readings: Signals, true: Signals, state: KinematicState, ctx: RecordingContext
    ) -> Signals:
        t = ctx.session_start_s + np.arange(len(true.acc)) / ctx.rate_hz
        bias = self.bias(t, ctx.rate_hz, ctx.seed)
        ctx.record(self.name, "mean_bias", {s: bias[s].mean(axis=0).tolist() for s in SENSORS})
        out = readings
        for s in SENSORS:
            out = out.with_sensor(s, out.sensor(s) + bias[s])
        return out

    def magnitude(self) -> Magnitude:
        """RMS change of one gyro bias axis between two instants ``HORIZON_S`` apart."""
        T = self.HORIZON_S
        var = self.gyr_rw**2 * T + 2 * self.gyr_gm**2 * (1 - np.exp(-T / self.gyr_tau_s))
        return Magnitude(
            float(np.sqrt(var)), "rad/s", f"RMS change of a gyro bias axis over {T:g} s"
        )
