"""Noise characterisation of a static recording: overlapping Allan deviation with confidence
intervals (:mod:`imucal.noise.allan`), the IEEE Std 952 / 1293 terms fitted to it
(:mod:`imucal.noise.fit`) and the stage that runs both on every sensor axis
(:mod:`imucal.noise.characterise`)."""

from imucal.noise.allan import (
    AllanDeviation,
    confidence_interval,
    equivalent_dof,
    octave_cluster_sizes,
    overlapping_adev,
)
from imucal.noise.characterise import FORMAT_VERSION, characterise_noise, sensor_noise
from imucal.noise.fit import TERMS, NoiseFit, TermFit, fit_noise_terms, term_adev, term_unit

__all__ = [
    "FORMAT_VERSION",
    "TERMS",
    "AllanDeviation",
    "NoiseFit",
    "TermFit",
    "characterise_noise",
    "confidence_interval",
    "equivalent_dof",
    "fit_noise_terms",
    "octave_cluster_sizes",
    "overlapping_adev",
    "sensor_noise",
    "term_adev",
    "term_unit",
]
