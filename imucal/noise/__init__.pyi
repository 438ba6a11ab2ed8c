from .allan import (
    AllanDeviation,
    confidence_interval,
    equivalent_dof,
    octave_cluster_sizes,
    overlapping_adev,
)
from .characterise import FORMAT_VERSION, characterise_noise, sensor_noise
from .fit import TERMS, NoiseFit, TermFit, fit_noise_terms, term_adev, term_unit
from .process import NoiseProcess, fit_noise_process, white_process
