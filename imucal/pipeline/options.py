"""The settings that change a fit, gathered once from the workflow's config.

Every path through the chain takes its settings from here: the stage rules (their ``params``),
the partial path, and the in-process chain that the diagnosis's twin, the closed loop and the
checks run (:func:`imucal.pipeline.full.calibrate_session`). A method chosen in the config
therefore changes the shipped calibration the same way whichever path produced it.

The defaults and units of every setting are those of ``workflow/schemas/config.schema.yaml``;
the dataclass defaults repeat them for callers without a config (tests, the simulator's checks)
and a test holds the two equal.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from imucal.io.dataset import Dataset


@dataclass(frozen=True)
class FitMethods:
    """The method chosen for each fit (config sections ``magnetometer``, ``accelerometer``,
    ``gyroscope``).

    Attributes
    ----------
    mag_refine_lm : bool
        Levenberg-Marquardt refinement of eq. 17 after the SVD fit.
    mag_alignment : {'full', 'paper'}
        T_R,mag from all samples of each phase, or the paper's extreme points.
    acc_cube : {'means', 'samples'}
        Eq. 32 on position means or on every static sample.
    acc_alignment : {'full', 'paper'}
        T_R,acc from all samples of each phase, or the paper's extreme points.
    gyr_bias_estimator : {'ls', 'mean'}
        Gyro bias from the LS slope of the cumulative sum (eqs. 34-35) or the plain mean.
    gyr_alignment : {'full', 'paper'}
        T_R,gyr from all samples of each phase, or the paper's two points (eqs. 28-31).
    """

    mag_refine_lm: bool = True
    mag_alignment: str = "full"
    acc_cube: str = "means"
    acc_alignment: str = "full"
    gyr_bias_estimator: str = "ls"
    gyr_alignment: str = "full"

    @classmethod
    def from_config(cls, config: Mapping) -> FitMethods:
        """The methods of a workflow config (its sections as validated by the schema)."""
        mag = config.get("magnetometer", {})
        acc = config.get("accelerometer", {})
        gyr = config.get("gyroscope", {})
        default = cls()
        return cls(
            mag_refine_lm=bool(mag.get("refine_lm", default.mag_refine_lm)),
            mag_alignment=mag.get("step2_method", default.mag_alignment),
            acc_cube=acc.get("cube_method", default.acc_cube),
            acc_alignment=acc.get("alignment_method", default.acc_alignment),
            gyr_bias_estimator=gyr.get("bias_estimator", default.gyr_bias_estimator),
            gyr_alignment=gyr.get("alignment_method", default.gyr_alignment),
        )

    @classmethod
    def of(cls, value: FitMethods | Mapping | None) -> FitMethods:
        """``value`` as methods: itself, from its dict form (a rule's params), or the defaults."""
        if isinstance(value, FitMethods):
            return value
        return cls(**(value or {}))


@dataclass(frozen=True)
class PipelineOptions:
    """Settings of the workflow that change the fit (``config.yaml``; schema defaults).

    Attributes
    ----------
    gravity_m_s2 : float
    sensitivity, range_counts : dict
        Sensor -> SI unit per count, largest |count| (``dataset.yaml``).
    ratetable : dict or None
        ``{'axes': [...], 'rates_dps': [...]}``.
    field_norm : float
    exact_rotation : bool
    lowpass_order : int
    lowpass_cutoff_hz : float
    methods : FitMethods
        The method of each fit.
    held_by_hand : tuple of str
        Recordings whose holds the segmentation found held by hand (tremor above the noise,
        :mod:`imucal.segments.holds`): not at rest, so their holds take no part in the resting
        statistics of the diagnosis. Set from the session's segments; a replica keeps the
        session's (its own holds are rendered without tremor).
    with_covariance : bool
        Carry the parameters' uncertainty into the calibration (the covariance and std of each
        sensor; step 1's through the alignment costs ten alignment refits per sensor) and give
        the alignments their covariance for residuals correlated in time (else the plain one).
        The diagnosis's twin replicas go without: nothing they are measured by reads it. It
        does not change the fitted values.
    ranges : dict or None
        Sensor -> its range in SI units where the recordings give it (a partial session's,
        :func:`imucal.ingest.sensor_limits`); a sensor absent has no known range. None: every
        sensor's is ``range_counts x sensitivity`` (a full-protocol session's native CSVs).
    """

    gravity_m_s2: float
    sensitivity: Mapping
    range_counts: Mapping
    ratetable: Mapping | None
    field_norm: float = 1.0
    exact_rotation: bool = True
    lowpass_order: int = 4
    lowpass_cutoff_hz: float = 5.0
    methods: FitMethods = field(default_factory=FitMethods)
    held_by_hand: tuple = ()
    with_covariance: bool = True
    ranges: Mapping | None = None

    @classmethod
    def of_dataset(cls, dataset: Dataset, **settings: Any) -> PipelineOptions:
        """The options of a dataset (``dataset.yaml``) with the workflow's ``settings``
        (:func:`pipeline_settings`; ``methods`` as a :class:`FitMethods` or its dict form)."""
        settings = dict(settings)
        settings["methods"] = FitMethods.of(settings.get("methods"))
        return cls(
            dataset.gravity_m_s2,
            dataset.sensitivity,
            dataset.range_counts,
            dataset.ratetable,
            dataset.field_norm,
            **settings,
        )

    def limit(self, sensor: str) -> float | None:
        """Sensor range in SI units (a reading with ``|value| >=`` it is clipped); None when it
        is not known (nothing is then left out as clipped)."""
        if self.ranges is not None:
            value = self.ranges.get(sensor)
            return None if value is None else float(value)
        return float(self.range_counts[sensor]) * float(self.sensitivity[sensor])


def pipeline_settings(config: Mapping) -> dict:
    """The settings of a workflow config that change a fit, in the form the rules pass as
    ``params`` and :meth:`PipelineOptions.of_dataset` takes (plain values, so that a changed
    setting reruns the rules that use it).

    Parameters
    ----------
    config : dict
        The workflow's config, validated against its schema (defaults filled in).

    Returns
    -------
    dict
        ``exact_rotation``, ``lowpass_order``, ``lowpass_cutoff_hz`` and ``methods`` (the
        :class:`FitMethods` fields).
    """
    return {
        "exact_rotation": bool(config["exact_rotation"]),
        "lowpass_order": int(config["lowpass"]["order"]),
        "lowpass_cutoff_hz": float(config["lowpass"]["cutoff_hz"]),
        "methods": asdict(FitMethods.from_config(config)),
    }
