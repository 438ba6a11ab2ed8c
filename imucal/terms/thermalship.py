"""Which temperature terms the pose hold-out takes, and the calibration that carries them.

The hold-out of :mod:`imucal.terms.poseholdout` judges each held-out pose, sensor and axis
(:func:`judge_cell`): the term is flagged where it predicts the held-out pose worse than no
term, or resolvably worse than a peer (the 95 % interval of term / peer with the fits' scatter
above 1), and it is not taken there. An axis whose term is taken in every held-out pose
ships its term, fitted on every pose (``shipped`` of the hold-out's result);
:func:`with_shipped_terms` puts those into a session's calibration: per sensor one
:class:`~imucal.modelterms.temperature.TemperaturePolynomial` (the axes that do not ship
carry zero coefficients), the bias moved to the polynomial's reference temperature, and what
was not shipped with the reason.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from imucal.modelterms import ModelTerms
from imucal.modelterms.temperature import (
    TEMPERATURE_SENSORS,
    TemperaturePolynomial,
    TemperatureTerm,
)

#: What the method string of a shipped polynomial says.
SHIPPED_METHOD = (
    "temperature hold-out across static poses (rule temperature_holdout): per axis, taken "
    "where it predicts every held-out pose better than no term and not resolvably worse than "
    "a peer; fitted on every pose's block means, one constant per pose"
)


def judge_cell(cell: Mapping, peers: Sequence[str], has_term: bool) -> dict:
    """The flags of one held-out cell and whether its term is taken.

    Parameters
    ----------
    cell : mapping
        ``term_ratio`` (term / none) and, per peer, ``term_vs_<peer>`` with its interval with
        the fits' scatter ``term_vs_<peer>_ci95``.
    peers : sequence of str
    has_term : bool
        Whether the cell's term has an order >= 1 (without one the term is no term: it cannot
        be worse than none, but a peer can still do better).

    Returns
    -------
    dict
        ``flags`` (sentences), ``flagged`` and ``taken`` (a term of order >= 1 without flags).
    """
    flags = []
    if has_term and cell["term_ratio"] > 1.0:
        lo, hi = cell["term_ratio_ci95"]
        flags.append(
            f"the term is worse than no term held out (term / none {cell['term_ratio']:.3f}, "
            f"{lo:.3f}-{hi:.3f})"
        )
    for peer in peers:
        lo, hi = cell[f"term_vs_{peer}_ci95"]
        if lo > 1.0:
            flags.append(
                f"{peer} is resolvably better (term / {peer} {cell[f'term_vs_{peer}']:.4f}, "
                f"{lo:.4f}-{hi:.4f})"
            )
    return {"flags": flags, "flagged": bool(flags), "taken": has_term and not flags}


def shipped_polynomials(holdout: Mapping, sensors: Sequence[str]) -> tuple[dict, dict]:
    """The polynomials a hold-out ships for ``sensors``, and the reasons for the rest.

    Parameters
    ----------
    holdout : mapping
        The result of :func:`imucal.terms.poseholdout.hold_out_recording` (its ``shipped``).
    sensors : sequence of str
        The sensors the calibration holds (a term needs the sensor's calibration).

    Returns
    -------
    polynomials : dict of str to TemperaturePolynomial
        Per sensor with at least one axis taken; the other axes' coefficients are zero.
    not_shipped : dict of str to str
        ``"<sensor> <axis>"`` -> why its term does not ship.
    """
    polynomials, not_shipped = {}, {}
    by_sensor: dict[str, list] = {}
    for entry in holdout.get("shipped", []):
        by_sensor.setdefault(entry["sensor"], []).append(entry)
    for sensor, entries in by_sensor.items():
        taken = [e for e in entries if e["taken"]]
        for e in entries:
            if not e["taken"]:
                not_shipped[f"{sensor} {e['axis']}"] = e["reason"]
            elif sensor not in sensors:
                not_shipped[f"{sensor} {e['axis']}"] = (
                    "the hold-out takes a term, but no calibration of this sensor ships"
                )
            elif sensor not in TEMPERATURE_SENSORS:
                not_shipped[f"{sensor} {e['axis']}"] = (
                    f"the hold-out takes a term, but the model has temperature terms of "
                    f"{list(TEMPERATURE_SENSORS)} only"
                )
        taken = [e for e in taken if sensor in sensors and sensor in TEMPERATURE_SENSORS]
        if taken:
            polynomials[sensor] = _polynomial(sensor, taken)
    return polynomials, not_shipped


def _polynomial(sensor: str, taken: Sequence[Mapping]) -> TemperaturePolynomial:
    """One sensor's polynomial from its shipped axes (same reference and span)."""
    axes = {"x": 0, "y": 1, "z": 2}
    order = max(e["order"] for e in taken)
    bias, std = np.zeros((order, 3)), np.zeros((order, 3))
    cov = np.zeros((3, order, order))
    for e in taken:
        j, k = axes[e["axis"]], e["order"]
        bias[:k, j], std[:k, j] = e["coef"], e["coef_std"]
        cov[j, :k, :k] = e["covariance"]
    first = taken[0]
    return TemperaturePolynomial(
        sensor, first["reference_c"], tuple(first["span_c"]), first["margin_c"], bias,
        np.zeros((0, 3)), std, np.zeros((0, 3)), SHIPPED_METHOD, cov,
    )  # fmt: skip


def with_shipped_terms(calibration: Mapping, holdout: Mapping) -> dict:
    """A session's calibration (JSON dict) with the temperature terms its hold-out ships.

    The bias of a sensor with a polynomial is moved to the polynomial's reference
    temperature: a bias fitted on the poses' samples holds their mean level, which lies
    ``mean_drift`` (per axis, from the hold-out) above the level at ``reference_c``. Its
    standard deviation is kept (the shift is a function of the coefficients, whose own std
    the polynomial carries).

    Parameters
    ----------
    calibration : mapping
        The calibration as written (format 2; the sensors it holds as keys).
    holdout : mapping
        The hold-out's result.

    Returns
    -------
    dict
        A copy with ``terms`` (``temperature``) where something ships, and
        ``temperature_terms``: per sensor and axis ``shipped`` or the reason it is not.
    """
    out = dict(calibration)
    sensors = [s for s in ("acc", "gyr", "mag") if s in calibration]
    polynomials, not_shipped = shipped_polynomials(holdout, sensors)
    decisions = {f"{e['sensor']} {e['axis']}": "shipped" for e in holdout.get("shipped", [])}
    decisions.update(not_shipped)
    for sensor, poly in polynomials.items():
        shift = np.zeros(3)
        for e in holdout["shipped"]:
            if e["sensor"] == sensor and e["taken"]:
                shift["xyz".index(e["axis"])] = e["mean_drift"]
        axes = ", ".join(a for a, v in zip("xyz", poly.bias.any(axis=0)) if v)
        method = (
            f"{calibration[sensor].get('method', '')}; temperature term of {axes} (pose hold-out)"
        )
        out[sensor] = {**calibration[sensor], "method": method.lstrip("; "),
                       "bias": (np.asarray(calibration[sensor]["bias"]) - shift).tolist()}  # fmt: skip
    if polynomials:
        terms = ModelTerms(temperature=TemperatureTerm(polynomials))
        out["terms"] = {**calibration.get("terms", {}), **terms.to_dict()}
    out["temperature_terms"] = decisions
    return out
