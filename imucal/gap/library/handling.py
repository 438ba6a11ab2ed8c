"""Handling and disturbances: a module held by hand, knocked or shaken.

``hand_tremor``, ``shock`` and ``vibration``: their specs. Only recordings with an orientation
reference show knocks and a vibration line; their estimators live with the statistics they
share (:mod:`imucal.gap.disturbance`). No scope estimates a hand's tremor.
"""

from __future__ import annotations

from imucal.gap.disturbance import estimate_shock, estimate_vibration
from imucal.gap.effects import EffectModel
from imucal.gap.library.registry import register
from imucal.gap.library.spec import EffectSpec

_LIES_STILL = "a static recording lies still; holds held by hand are the segmentation's"
_NO_SPIKE_STATISTIC = (
    "no estimator on a static recording's streams (its statistics are Allan deviations and "
    "receive times, which do not isolate a few spikes); recordings with an orientation "
    "reference show knocks"
)
_NO_LINE_STATISTIC = (
    "no estimator on a static recording's streams (no spectral line statistic); recordings "
    "with an orientation reference show a line"
)

HAND_TREMOR = register(EffectSpec(
    name="hand_tremor",
    description="the cube's static positions held by hand: physiological tremor and a slow sway",
    kind="spread",
    scopes={
        "protocol": "the twin replays the protocol's plan on the platform; a hand's tremor "
        "changes how the protocol is carried out, which the segmentation reports (holds held "
        "by hand)",
        "static": _LIES_STILL,
        "motion": "the twin replays the recorded motion, tremor included",
        "rests": _LIES_STILL,
        "field_fit": _LIES_STILL,
    },
))  # fmt: skip

SHOCK = register(EffectSpec(
    name="shock",
    description="knocks and taps: short pulses in the accelerometer and the gyroscope",
    kind="systematic",
    scopes={
        "protocol": "the protocol's statistics are segment means and fits, not residuals "
        "against an independent attitude; a knock within a pose splits it at the static "
        "detector",
        "static": _NO_SPIKE_STATISTIC,
        "motion": EffectModel("shock", estimate_shock,
                              (("reference", "gyr", "shock_rate"),
                               ("reference", "gyr", "resid_rms")),
                              "knocks: accelerometer spikes of a few ms where the gyroscope "
                              "departs from the reference"),
        "rests": "no estimator on the rests' statistics (noise level, short Allan deviation, "
        "trend, quantisation, timing do not isolate a few spikes)",
        "field_fit": _NO_SPIKE_STATISTIC,
    },
))  # fmt: skip

VIBRATION = register(EffectSpec(
    name="vibration",
    description="a narrow band in the accelerometer and gyroscope: a machine, a robot's drives",
    kind="systematic",
    scopes={
        "protocol": "no spectral statistic in the protocol's gap map; a vibration within a "
        "pose raises the noise the static detector's threshold is set from",
        "static": _NO_LINE_STATISTIC,
        "motion": EffectModel("vibration", estimate_vibration,
                              (("reference", "gyr", "line_power"),
                               ("reference", "gyr", "resid_rms")),
                              "a line in the gyroscope the reference does not follow (a "
                              "machine, a robot's drives)"),
        "rests": "no estimator on the rests' statistics (no spectral line statistic)",
        "field_fit": _NO_LINE_STATISTIC,
    },
))  # fmt: skip
