"""The gap diagnosis in a lab engineer's words: a plain label and a size in physical units for
every effect, a plain label and a unit for every statistic, and the place of a location.

Everything the report says about ``diagnosis.json`` in words comes from here, keyed by the
names the diagnosis writes (effects: :func:`imucal.gap.catalogue.catalogue`, statistics:
:data:`imucal.gap.statistics.CATALOGUE`); ``tests/report/test_gapwords.py`` walks both and
fails when one lacks its words. An effect's size is computed from the parameters its estimator
wrote (SI; the names say the unit, as in the simulator's effects), so it reads the same for a
recorded session and for its twin.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Unit of a sensor's SI reading (the magnetometer is normalised: field norm 1).
SENSOR_UNITS = {"acc": "m/s²", "gyr": "rad/s", "mag": "normalised"}
#: What a location's sensor field names.
SENSOR_WORDS = {
    "acc": "accelerometer",
    "gyr": "gyroscope",
    "mag": "magnetometer",
    "clock": "clock",
    "*": "all sensors",
}
#: What a location's stage field names: the part of the session its statistic describes.
STAGE_WORDS = {
    "ingest": "packets",
    "noise": "noise",
    "acc_cube": "cube positions",
    "acc_table": "rate-table runs",
    "gyr_static": "rests",
    "gyr_table": "rate table",
    "gyr_scale": "tool-free scale",
    "mag": "magnetometer fits",
    "validate": "reference clock",
    "temperature": "temperature",
    "reference": "orientation reference",
    "field_fit": "field fit",
}
#: Degrees per radian.
DEG = 180.0 / math.pi
#: Standard gravity (m/s^2): g-sensitivities are quoted per g as datasheets do.
G_STANDARD = 9.80665


def number(value: Any, digits: int = 3) -> str:
    """A number with ``digits`` significant digits, plain notation from 1e-3 to 1e5."""
    x = float(value)
    if not math.isfinite(x):
        return "n/a"
    if x == 0:
        return "0"
    if 1e-3 <= abs(x) < 1e5:
        decimals = max(digits - 1 - math.floor(math.log10(abs(x))), 0)
        text = f"{x:.{decimals}f}"
        return text.rstrip("0").rstrip(".") if "." in text else text
    mantissa, exponent = f"{x:.{digits - 1}e}".split("e")
    mantissa = mantissa.rstrip("0").rstrip(".") if "." in mantissa else mantissa
    return f"{mantissa} × 10{str(int(exponent)).translate(_SUPERSCRIPTS)}"


_SUPERSCRIPTS = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


# --------------------------------------------------------------------------------------------
# Statistics


@dataclass(frozen=True)
class StatisticWords:
    """A statistic in words.

    Attributes
    ----------
    label : str
        Plain label, short enough for a figure's axis (about 30 characters).
    unit : str
        Its unit; ``{sensor}`` stands for the unit of the location's sensor
        (:data:`SENSOR_UNITS`), empty for a pure number.
    """

    label: str
    unit: str


#: Every statistic the diagnosis scores, in words.
STATISTICS = {
    # timing of the packets
    "loss_fraction": StatisticWords("share of packets lost", ""),
    "stamp_scatter_s": StatisticWords("time-stamp scatter", "s"),
    "stamp_wander_s": StatisticWords("time-stamp wander", "s"),
    "burst_fraction": StatisticWords("share of packets back to back", ""),
    "long_gap_fraction": StatisticWords("share of long receive gaps", ""),
    "clip_fraction": StatisticWords("share of readings at the range", ""),
    # noise of a static recording or of the rests
    "adev_10s_excess": StatisticWords("Allan dev. at 10 s over white", "ln ratio"),
    "adev_long_excess": StatisticWords("Allan dev. at long τ over white", "ln ratio"),
    "trend_per_s": StatisticWords("linear trend at rest", "{sensor}/s"),
    "rest_noise": StatisticWords("white noise of the rests", "{sensor}"),
    "rest_still_fraction": StatisticWords("share of unchanged readings", ""),
    "rest_adev_excess": StatisticWords("Allan dev. of the rests over white", "ln ratio"),
    "rest_trend_per_s": StatisticWords("trend of the rests", "{sensor}/s"),
    # accelerometer cube
    "resid_rms": StatisticWords("residual RMS", "{sensor}"),
    "resid_time_slope": StatisticWords("residual trend in time", "{sensor}/s"),
    "dir_resid_rad": StatisticWords("direction residual RMS", "rad"),
    # gyroscope at rest
    "spread": StatisticWords("spread of the rest means", "rad/s"),
    "g_slope": StatisticWords("rate per specific force", "(rad/s)/(m/s²)"),
    "vertical": StatisticWords("rate along the vertical", "rad/s"),
    "world_rate": StatisticWords("rate fixed in the world", "rad/s"),
    # rate table and scale
    "rate2": StatisticWords("residual ∝ rate²", "1/(rad/s)"),
    "rate3": StatisticWords("residual ∝ rate³", "1/(rad/s)²"),
    "left_out": StatisticWords("rate-table runs left out", "runs"),
    "omega2": StatisticWords("specific force ∝ rate²", "m"),
    "scale_ratio": StatisticWords("tool-free / final scale", ""),
    # magnetometer
    "dip_spread_rad": StatisticWords("spread of the dip angle", "rad"),
    "lag_s": StatisticWords("lag behind the gyroscope", "s"),
    "norm_spread": StatisticWords("spread of |m| over rests", "normalised"),
    "platform_field": StatisticWords("field turning with the platform", "normalised"),
    # reference clock, temperature
    "ref_offset_s": StatisticWords("reference clock offset", "s"),
    "ref_drift_ppm": StatisticWords("reference clock drift", "ppm"),
    "temp_slope": StatisticWords("rest residual per kelvin", "{sensor}/K"),
    # a magnetometer turned without rests
    "fit_resid_rms": StatisticWords("field-fit residual RMS", "normalised"),
    "fit_resid_slow": StatisticWords("slow part of the residual", "ln ratio"),
    "fit_resid_direction": StatisticWords("residual by direction", "normalised"),
    # against an orientation reference
    "ori_median_rad": StatisticWords("orientation error, median", "rad"),
    "ref_scale": StatisticWords("gyroscope per reference rate", ""),
    "ref_g_slope": StatisticWords("rate error per specific force", "(rad/s)/(m/s²)"),
    "shock_rate": StatisticWords("knocks per second", "1/s"),
    "line_power": StatisticWords("power of a spectral line", "(rad/s)²"),
    "field_position_rms": StatisticWords("field change with position", "normalised"),
    "field_dipole_peak": StatisticWords("peak field of a nearby dipole", "normalised"),
}


def statistic_label(name: str) -> str:
    """Plain label of a statistic (the name itself when it has none: a newer diagnosis)."""
    words = STATISTICS.get(name)
    return words.label if words else name


def statistic_unit(name: str, sensor: str = "") -> str:
    """Unit of a statistic at a location of ``sensor`` (``{sensor}`` filled in)."""
    words = STATISTICS.get(name)
    if words is None:
        return ""
    return words.unit.replace("{sensor}", SENSOR_UNITS.get(sensor, "SI"))


def location_place(location: Mapping) -> str:
    """Where a location lies, in words: ``gyroscope y, rate table (runs)``."""
    sensor = SENSOR_WORDS.get(str(location.get("sensor")), str(location.get("sensor")))
    axis = str(location.get("axis", "-"))
    stage = STAGE_WORDS.get(str(location.get("stage")), str(location.get("stage")))
    segment = str(location.get("segment", "all"))
    what = sensor if axis in ("-", "all") else f"{sensor} {axis}"
    where = stage if segment in ("all", "-") else f"{stage}, {segment}"
    return f"{what}, {where}"


def location_phrase(location: Mapping) -> str:
    """A location in a sentence: its statistic's label with the sensor and segment it was
    taken at, ``reference clock offset (clock, rotation3d)``."""
    sensor = SENSOR_WORDS.get(str(location.get("sensor")), str(location.get("sensor")))
    axis, segment = str(location.get("axis", "-")), str(location.get("segment", "all"))
    where = [sensor if axis in ("-", "all") else f"{sensor} {axis}"]
    if segment not in ("all", "-"):
        where.append(segment)
    return f"{statistic_label(str(location.get('statistic')))} ({', '.join(where)})"


def location_label(location: Mapping) -> str:
    """A location in words: its statistic's label, unit and place."""
    name = str(location.get("statistic"))
    unit = statistic_unit(name, str(location.get("sensor")))
    return f"{statistic_label(name)}{f' ({unit})' if unit else ''}: {location_place(location)}"


# --------------------------------------------------------------------------------------------
# Effects


def _get(params: Mapping, key: str) -> float | None:
    value = params.get(key)
    if isinstance(value, (int, float, np.number)) and not isinstance(value, bool):
        return float(value)
    return None


def _peak(params: Mapping, key: str) -> float | None:
    value = params.get(key)
    if value is None:
        return None
    x = np.abs(np.asarray(value, dtype=float))
    return float(x.max()) if x.size else None


def _join(parts: list[str | None]) -> str:
    return ", ".join(p for p in parts if p)


def _ms(seconds: float) -> str:
    """A duration in ms below 0.1 s, else in s."""
    return f"{number(seconds * 1e3)} ms" if abs(seconds) < 0.1 else f"{number(seconds)} s"


def _time_offset(p: Mapping) -> str:
    offset, drift = _get(p, "offset_s"), _get(p, "drift_ppm")
    head = None
    if offset is not None:
        when = "before" if offset > 0 else "after"
        head = f"the reference started {_ms(abs(offset))} {when} the module"
    return _join([head, f"its clock drifts {number(drift)} ppm" if drift else None])


def _clock_drift(p: Mapping) -> str:
    ppm = _get(p, "ppm")
    if ppm is None:
        return ""
    faster = "faster" if ppm > 0 else "slower"
    return f"the module's logger clock runs {number(abs(ppm))} ppm {faster} than the reference's"


def _packet_loss(p: Mapping) -> str:
    fraction, burst = _get(p, "fraction"), _get(p, "burst_mean")
    head = f"{number(100 * fraction, 2)} % of the packets lost" if fraction is not None else None
    if p.get("model") == "bernoulli":
        return _join([head, "one at a time"])
    tail = f"in bursts of {number(burst, 2)} packets on average" if burst is not None else None
    return " ".join(t for t in (head, tail) if t)


def _lever_arm(p: Mapping) -> str:
    r = [_get(p, k) for k in ("x_m", "y_m", "z_m")]
    if any(v is None for v in r):
        return ""
    cm = ", ".join(number(100 * v, 2) for v in r)
    return (
        f"the accelerometer {number(100 * float(np.linalg.norm(r)), 2)} cm from the centre of "
        f"rotation (x, y, z: {cm} cm)"
    )


def _g_sensitivity(p: Mapping) -> str:
    peak = _peak(p, "matrix")
    if peak is None:
        return ""
    return (
        f"gyroscope rate per specific force up to {number(peak)} (rad/s)/(m/s²) "
        f"({number(peak * DEG * G_STANDARD)} °/s per g)"
    )


def _earth_rotation(p: Mapping) -> str:
    rate, lat = _get(p, "rate_rad_s"), _get(p, "latitude_deg")
    return _join(
        [
            f"a rate fixed in the world of {number(rate * DEG * 3600)} °/h" if rate else None,
            f"latitude {number(lat)}°" if lat is not None else None,
        ]
    )


def _saturation(p: Mapping) -> str:
    parts = [
        f"{SENSOR_WORDS[s]} clipped at ±{int(p[s])} counts"
        for s in ("acc", "gyr", "mag")
        if _get(p, s) is not None and int(p[s]) < 32767
    ]
    return _join(parts) or "no sensor clipped below ±32767 counts"


def _per_sensor(p: Mapping, suffix: str, unit: Callable[[str], str], scale: float = 1.0) -> str:
    parts = []
    for s in ("acc", "gyr", "mag"):
        peak = _peak(p, f"{s}{suffix}")
        if peak:
            parts.append(f"{SENSOR_WORDS[s]} up to {number(peak * scale)} {unit(s)}")
    return _join(parts)


def _temperature_drift(p: Mapping) -> str:
    bias = _per_sensor(p, "_per_k", lambda s: f"{SENSOR_UNITS[s]} per K")
    gyro = _peak(p, "gyr_per_k")
    if gyro:
        bias = bias.replace("rad/s per K", f"rad/s per K ({number(gyro * DEG)} °/s per K)")
    scale = _per_sensor(p, "_scale_per_k", lambda s: "% per K", 100.0)
    return _join(
        [
            f"bias drift: {bias}" if bias else None,
            f"scale drift: {scale}" if scale else None,
            _temperature_path(p),
        ]
    )


def _temperature_path(p: Mapping) -> str | None:
    """The temperature the drift follows in the twin: the recorded path (no warm-up curve was
    an estimate: the estimator's flag says why), a warm-up whose rise and time constant are
    estimates, or nothing where the parameters name neither."""
    path = p.get("path_c")
    if path:
        lo, hi = float(np.min(path)), float(np.max(path))
        return (
            f"on the recorded temperature, {number(lo)}-{number(hi)} °C (no warm-up curve fits it)"
        )
    rise, tau = _get(p, "rise_c"), _get(p, "tau_s")
    if rise is None or tau is None:
        return None
    return f"over a warm-up of {number(rise)} K with a time constant of {number(tau)} s"


def _bias_instability(p: Mapping) -> str:
    parts = []
    for s in ("acc", "gyr", "mag"):
        gm, rw, tau = _get(p, f"{s}_gm"), _get(p, f"{s}_rw"), _get(p, f"{s}_tau_s")
        unit = SENSOR_UNITS[s]
        if gm:
            corr = f", correlation time {number(tau)} s" if tau else ""
            parts.append(f"{SENSOR_WORDS[s]} bias wandering by {number(gm)} {unit} (std{corr})")
        if rw:
            parts.append(f"{SENSOR_WORDS[s]} bias random walk {number(rw)} {unit}/√s")
    return _join(parts) or "no bias wander"


def _scale_nonlinearity(p: Mapping) -> str:
    parts = []
    for s in ("acc", "gyr", "mag"):
        k2, k3 = _get(p, f"{s}_k2"), _get(p, f"{s}_k3")
        if k2 or k3:
            parts.append(
                f"{SENSOR_WORDS[s]} off its line by {number(100 * (k2 or 0), 2)} % (square) and "
                f"{number(100 * (k3 or 0), 2)} % (cube) of full scale at full scale"
            )
    return _join(parts) or "no departure from a straight line"


def _mag_latency(p: Mapping) -> str:
    delay, rate = _get(p, "delay_s"), _get(p, "rate_hz")
    return _join(
        [
            f"the magnetometer {_ms(delay)} late" if delay is not None else None,
            f"sampled at {number(rate)} Hz" if rate else None,
        ]
    )


def _platform_magnetic(p: Mapping) -> str:
    field = [_get(p, k) or 0.0 for k in ("field_x", "field_y", "field_z")]
    current = _get(p, "current_per_rad_s2")
    return _join(
        [
            f"a field of {number(float(np.linalg.norm(field)))} (normalised) turning with the "
            "platform",
            f"and {number(current)} (normalised) per rad/s² of its angular acceleration"
            if current
            else None,
        ]
    )


def _placement_error(p: Mapping) -> str:
    cube, table = _get(p, "cube_sigma_deg"), _get(p, "table_sigma_deg")
    return _join(
        [
            f"cube positions off by {number(cube, 2)}° (std)" if cube is not None else None,
            f"rate-table mountings by {number(table, 2)}°" if table is not None else None,
        ]
    )


def _large_misalignment(p: Mapping) -> str:
    parts = [
        f"{SENSOR_WORDS[s]} {number(p[f'{s}_deg'], 2)}°"
        for s in ("acc", "gyr", "mag")
        if _get(p, f"{s}_deg") is not None
    ]
    return f"misalignment {_join(parts)}" if parts else ""


def _hand_tremor(p: Mapping) -> str:
    sway, tremor = _get(p, "sway_deg"), _get(p, "tremor_deg")
    return _join(
        [
            f"sway {number(sway, 2)}°" if sway is not None else None,
            f"tremor {number(tremor, 2)}°" if tremor is not None else None,
        ]
    )


def _jitter(what: str) -> Callable[[Mapping], str]:
    def size(p: Mapping) -> str:
        std = _get(p, "std_s")
        return f"{what} scattered by {_ms(std)} (std)" if std is not None else ""

    return size


def _world_magnetic(p: Mapping) -> str:
    moment = float(np.linalg.norm([_get(p, f"moment_{a}") or 0.0 for a in "xyz"]))
    xx, yy, xy, xz, yz = (_get(p, f"grad_{k}") or 0.0 for k in ("xx", "yy", "xy", "xz", "yz"))
    # |G| (Frobenius) of the symmetric, traceless gradient from its five free entries
    gradient = math.sqrt(xx**2 + yy**2 + (xx + yy) ** 2 + 2 * (xy**2 + xz**2 + yz**2))
    parts = []
    if moment:
        where = float(np.linalg.norm([_get(p, f"dipole_{a}_m") or 0.0 for a in "xyz"]))
        parts.append(
            f"a magnet of moment {number(moment)} Earth fields × m³ {number(where, 2)} m from "
            "the pivot"
        )
    if gradient:
        parts.append(f"a field gradient of {number(gradient)} Earth fields per m")
    return _join(parts)


def _shock(p: Mapping) -> str:
    rate, acc, gyr = (_get(p, k) for k in ("rate_per_s", "acc_peak_m_s2", "gyr_peak_rad_s"))
    return _join(
        [
            f"{number(rate * 60, 2)} knocks per minute" if rate is not None else None,
            f"peaks {number(acc)} m/s²" if acc is not None else None,
            f"{number(gyr)} rad/s" if gyr is not None else None,
        ]
    )


def _vibration(p: Mapping) -> str:
    freq, acc, gyr = (_get(p, k) for k in ("freq_hz", "acc_amp_m_s2", "gyr_amp_rad_s"))
    return _join(
        [
            f"a vibration at {number(freq)} Hz" if freq is not None else None,
            f"{number(acc)} m/s²" if acc is not None else None,
            f"{number(gyr)} rad/s" if gyr is not None else None,
        ]
    )


@dataclass(frozen=True)
class EffectWords:
    """An effect in words.

    Attributes
    ----------
    label : str
        What it is, plainly (a noun phrase).
    size : callable
        The effect's parameters (as its estimator writes them, SI) -> its size in physical
        units, one phrase; empty when the parameters do not give one.
    """

    label: str
    size: Callable[[Mapping], str]


#: Every effect of the simulator's library, in words.
EFFECTS = {
    "time_offset": EffectWords("an offset of the reference's clock", _time_offset),
    "clock_drift": EffectWords(
        "a rate error between the logger's and the reference's clocks", _clock_drift
    ),  # fmt: skip
    "packet_loss": EffectWords("packet loss", _packet_loss),
    "timing_jitter": EffectWords("jitter of the receive time stamps", _jitter("time stamps")),
    "lever_arm": EffectWords("a lever arm of the accelerometer", _lever_arm),
    "g_sensitivity": EffectWords("a g-sensitivity of the gyroscope", _g_sensitivity),
    "earth_rotation": EffectWords("the Earth's rotation", _earth_rotation),
    "saturation": EffectWords("clipping at the sensor's range", _saturation),
    "temperature_drift": EffectWords("a temperature drift", _temperature_drift),
    "bias_instability": EffectWords("a wandering bias", _bias_instability),
    "scale_nonlinearity": EffectWords("a non-linear scale", _scale_nonlinearity),
    "mag_latency": EffectWords("a delay of the magnetometer", _mag_latency),
    "platform_magnetic": EffectWords("a magnetic field of the platform", _platform_magnetic),
    "placement_error": EffectWords("placement errors of the poses", _placement_error),
    "large_misalignment": EffectWords("a large misalignment", _large_misalignment),
    "hand_tremor": EffectWords("holds by hand", _hand_tremor),
    "reference_jitter": EffectWords(
        "jitter of the reference's sample times", _jitter("the reference's sample times")
    ),
    "world_magnetic": EffectWords("a magnetic field fixed near the path", _world_magnetic),
    "shock": EffectWords("knocks", _shock),
    "vibration": EffectWords("a vibration", _vibration),
}


def effect_label(name: str) -> str:
    """Plain label of an effect (its name with spaces when it has none: a newer diagnosis)."""
    words = EFFECTS.get(name)
    return words.label if words else name.replace("_", " ")


def effect_size(name: str, params: Mapping | None) -> str:
    """An effect's size in physical units from its estimated parameters ('' if unknown)."""
    words = EFFECTS.get(name)
    if words is None or not params:
        return ""
    return words.size(params)
