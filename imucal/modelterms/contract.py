"""The contract every optional model term keeps, and what its correction sees of a recording.

A term of the calibration model (``docs/model-terms.md``) is one class deriving from
:class:`ModelTerm`, registered once (:mod:`imucal.modelterms.registry`). The class states its name
(its key in ``calibration.json`` and in the config's ``terms``), the effect of the catalogue it
answers (:mod:`imucal.gap.catalogue`), the export formats that carry it, what of a recording its
correction needs and what its estimator holds out; an instance is a fitted term: its
correction, the variance its coefficients give the calibrated values, its dict form, its report
rows, what apply reports of its flags and what an export says of it.
:class:`imucal.calibration.ImuCalibration`, apply, the held-out check, the report and the
exports loop over the registered terms; none of them names one. A term that is one coefficient
with its standard deviation, a unit and a method derives from :class:`ValueTerm`, which writes
its check, dict form and report row from its declared field names, shape, unit and label.

The model's chain (eq. 11 with the terms, :mod:`imucal.modelterms`): the bracket of each sensor
(``reading - bias``, corrected by the terms that act on the reading before the matrix), the
matrix, then the terms that act on the calibrated values, in the registry's order.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np


@dataclass(frozen=True)
class Samples:
    """What a term's correction sees of one recording besides the calibrated values.

    Attributes
    ----------
    readings : dict of str to ndarray, shape (n, 3)
        Sensor -> readings in SI units (sensor frame), rows of one sample.
    calibration : dict of str to SensorCalibration
        Sensor -> the paper's bias and matrix (the terms' reference).
    temp_c : ndarray, shape (n,), or None
        Temperature of each sample (deg C).
    t_s : ndarray, shape (n,), or None
        Time of each sample (s).
    source : str
        What the readings come from (a file name), named in errors.
    """

    readings: Mapping[str, np.ndarray]
    calibration: Mapping[str, Any]
    temp_c: np.ndarray | None = None
    t_s: np.ndarray | None = None
    source: str = "the recording"


#: The fields of :class:`Samples` a term may need beyond the readings (:attr:`ModelTerm.needs`).
SAMPLE_INPUTS = ("temp_c", "t_s")


@dataclass(frozen=True)
class ReportRow:
    """One coefficient (or block of them) of a term as the report shows it.

    Attributes
    ----------
    name : str
        What it is ('g-sensitivity G').
    value, std : float or nested list of float
        The value and its standard deviation, same shape.
    unit : str
    """

    name: str
    value: Any
    std: Any
    unit: str


class ModelTerm(ABC):
    """An optional term of the calibration model: a frozen dataclass deriving from this.

    Class attributes
    ----------------
    name : str
        Key of the term in ``calibration.json``'s ``terms`` and in the config's ``terms``.
    effect : str
        The effect of the catalogue (:mod:`imucal.gap.catalogue`) the term answers.
    exported_by : frozenset of str
        Export formats (:data:`imucal.export.FORMATS`) that carry the term; the others name it
        among the terms they leave out (:meth:`export_note`).
    refits_session : bool
        Whether the closed loop estimates the later terms on the session corrected by this one
        and calibrated again (a term on the readings, such as a temperature drift, changes the
        bias and matrices the later terms are estimated against).
    needs : frozenset of str
        What of a recording besides its readings the correction reads: fields of
        :class:`Samples` among :data:`SAMPLE_INPUTS` (``temp_c``: the recording's temperature
        column; ``t_s``: its sample times). Apply hands them over only when a term needs them.
    heldout_residual : str or None
        What the estimator's held-out residual is (for terms.json and the report; units in
        parentheses), None when the estimator holds nothing out (:meth:`heldout_rms`).
    switch_description : str
        What the term is, with its unit: the description of its switch ``terms.<name>`` in the
        config (off, on, or auto when the diagnosis accepts :attr:`effect`).
    options : dict of str to dict
        The term's own settings: option -> the JSON schema of the config key
        ``terms.<name>_<option>`` (type, bounds, ``default`` and a ``description`` with the
        unit). The config schema's section ``terms`` is made of the registered terms'
        switches and options (:func:`imucal.modelterms.registry.settings_schema`), and the
        term's estimator receives its options as keyword arguments.

    The estimator of a term is not part of its class: it needs the fitted session, which lives
    in the layers above the model, and is found by the term's name in
    :mod:`imucal.terms.estimators`.
    """

    name: ClassVar[str]
    effect: ClassVar[str]
    exported_by: ClassVar[frozenset] = frozenset()
    refits_session: ClassVar[bool] = False
    needs: ClassVar[frozenset] = frozenset()
    heldout_residual: ClassVar[str | None] = None
    switch_description: ClassVar[str]
    options: ClassVar[Mapping[str, Mapping]] = {}

    @classmethod
    def heldout_rms(cls, evidence: Mapping) -> tuple[float, float, int] | None:
        """The held-out RMS without and with the term and the number of held-out values, from
        the evidence of its estimator (:mod:`imucal.terms.estimators`); None when the term or this estimate has none.

        By default the evidence's ``heldout_rms`` (``without``, ``with`` and ``values``, or the
        evidence's ``segments`` for the number); a term whose estimator records it otherwise
        overrides this.
        """
        if cls.heldout_residual is None:
            return None
        rms = evidence.get("heldout_rms")
        if not rms:
            return None
        n = rms.get("values", evidence.get("segments", 0))
        return rms["without"], rms["with"], int(n)

    def check(self, samples: Samples) -> dict:
        """Refuse samples the term cannot calibrate; say what it flags (JSON-ready, empty for
        nothing). Called once per recording before :meth:`correct_reading`.

        Raises
        ------
        ValueError
            Naming ``samples.source`` and what the term needs.
        """
        return {}

    def flag_report(self, flags: Mapping, source: str) -> tuple[dict, list[str]]:
        """What apply writes into the output's metadata for the flags :meth:`check` returned,
        and the warnings it logs for them (none by default).

        Parameters
        ----------
        flags : dict
            The term's flags, non-empty.
        source : str
            What the samples come from (a file name), for the warnings.

        Returns
        -------
        metadata : dict
            Keys to add to the calibrated recording's metadata.
        warnings : list of str
        """
        return {}, []

    def correct_reading(self, sensor: str, bracket: np.ndarray, samples: Samples) -> np.ndarray:
        """The bracket of eq. 11 of ``sensor`` (n, 3; ``reading - bias`` and the corrections
        of the terms before) with this term's correction on the reading; unchanged by
        default."""
        return bracket

    def correct(self, values: Mapping[str, np.ndarray], samples: Samples) -> dict:
        """The calibrated values (sensor -> (n, 3), frame B, SI; by the model up to this term)
        with this term's correction; unchanged by default."""
        return dict(values)

    @abstractmethod
    def variance(
        self,
        values: Mapping[str, np.ndarray],
        brackets: Mapping[str, np.ndarray],
        samples: Samples,
    ) -> dict:
        """Variance (sensor -> (n, 3), SI^2) the term's coefficients give the calibrated
        values, first order, from their standard deviations.

        Parameters
        ----------
        values : dict of str to ndarray, shape (n, 3)
            Calibrated by the model up to this term (what :meth:`correct` receives).
        brackets : dict of str to ndarray, shape (n, 3)
            Each sensor's bracket with every term's reading correction (what the matrix
            multiplies).
        samples : Samples
        """

    @abstractmethod
    def to_dict(self) -> dict:
        """The term's entry in ``calibration.json`` (JSON-ready, with units)."""

    @classmethod
    @abstractmethod
    def from_dict(cls, d: Mapping) -> ModelTerm:
        """The term from its entry in ``calibration.json``.

        Raises
        ------
        ValueError
            Naming the term and the missing or malformed key.
        """

    @abstractmethod
    def report_rows(self) -> list[ReportRow]:
        """The term's coefficients with their standard deviations and units, for the report."""

    def export_note(self, fmt: str) -> str | None:
        """What an export file of format ``fmt`` says of the term it leaves out (listed in its
        header), None when the format carries it."""
        return None if fmt in self.exported_by else self.name


def _requirement(shape: tuple[int, ...]) -> str:
    """What a coefficient of ``shape`` must be, for error messages."""
    if shape == ():
        return "finite"
    if len(shape) == 1:
        return f"{shape[0]} finite values"
    return f"a finite {'x'.join(map(str, shape))} matrix"


class ValueTerm(ModelTerm):
    """A term that is one coefficient (a scalar, vector or matrix) with its standard deviation,
    a unit and a method: its check, dict form and report row follow from class attributes.

    The subclass is a frozen dataclass with the fields named by ``value_field`` and
    ``std_field`` (in that order) and ``method: str = ""``; it writes its correction, variance
    and estimator.

    Class attributes
    ----------------
    value_field, std_field : str
        Names of the coefficient's field and of its standard deviations' (their keys in
        ``calibration.json`` too).
    value_shape : tuple of int
        Shape of both: ``()`` for a float, ``(3,)``, ``(3, 3)`` for arrays.
    unit : str
        The ``unit`` entry of the dict form and the unit of the report row.
    report_label : str
        Name of the report row.
    """

    value_field: ClassVar[str]
    std_field: ClassVar[str]
    value_shape: ClassVar[tuple[int, ...]]
    unit: ClassVar[str]
    report_label: ClassVar[str]

    def __post_init__(self) -> None:
        """Coefficient and standard deviations as finite floats of ``value_shape``.

        Raises
        ------
        ValueError
            Naming the term, the field and the shape expected.
        """
        for field in (self.value_field, self.std_field):
            value = getattr(self, field)
            if self.value_shape == ():
                v = float(value)
                ok = bool(np.isfinite(v))
            else:
                v = np.asarray(value, dtype=float)
                ok = v.shape == self.value_shape and bool(np.all(np.isfinite(v)))
            if not ok:
                raise ValueError(
                    f"{self.name}.{field} must be {_requirement(self.value_shape)}, got {v!r}"
                )
            object.__setattr__(self, field, v)

    def to_dict(self) -> dict:
        value, std = (getattr(self, f) for f in (self.value_field, self.std_field))
        return {
            self.value_field: value.tolist() if isinstance(value, np.ndarray) else value,
            self.std_field: std.tolist() if isinstance(std, np.ndarray) else std,
            "unit": self.unit,
            "method": self.method,
        }

    @classmethod
    def from_dict(cls, d: Mapping) -> ValueTerm:
        """The term from its entry (a missing standard deviation is zero, a missing method
        empty).

        Raises
        ------
        ValueError
            If the entry lacks the coefficient.
        """
        if cls.value_field not in d:
            raise ValueError(f"{cls.name} term lacks the key {cls.value_field!r}")
        return cls(
            **{
                cls.value_field: d[cls.value_field],
                cls.std_field: d.get(cls.std_field, np.zeros(cls.value_shape)),
                "method": d.get("method", ""),
            }
        )

    def report_rows(self) -> list[ReportRow]:
        d = self.to_dict()
        return [ReportRow(self.report_label, d[self.value_field], d[self.std_field], self.unit)]
