"""Run scikit-diveMove's own ``IMUcalibrate.build_tmodels`` on the CATS recording; peers venv.

Usage: ``<venv>/bin/python skdivemove_adapter.py <cats_temperature_calib.nc> <out.json>``.

The PyPI wheel ``scikit-diveMove==0.4.0`` is installed without its dependencies on R: its
package ``__init__`` imports the TDR tools, which load R's diveMove through ``rpy2`` at import
time. The temperature models do not use R, so the package's shell and its R bridge
(``skdiveMove.core``) are stood in for by empty modules and ``skdiveMove.imutools.imucalibrate``
is imported from the wheel as it ships. The calls are those of the peer's own test
(``skdiveMove/tests/test_imucalibrate.py``): its periods, ``axis_order`` ``zxy``, ``win_len``
119, accelerometer and magnetometer with ``use_axis_order=True``, the gyroscope with
``use_axis_order=False``, each without and with ``T_brk=10``.
"""

import importlib.util
import json
import sys
import types
from pathlib import Path

PERIODS = [
    ("2021-09-20T09:00:00", "2021-09-21T10:33:00"),
    ("2021-09-21T10:40:00", "2021-09-22T11:55:00"),
    ("2021-09-22T12:14:00", "2021-09-23T11:19:00"),
]
CALLS = {"acceleration": True, "angular_velocity": False, "magnetic_density": True}
WIN_LEN = int(2 * 60 * 1) - 1


def _import_peer():
    spec = importlib.util.find_spec("skdiveMove")
    root = Path(next(iter(spec.submodule_search_locations)))
    for name, path in (("skdiveMove", root), ("skdiveMove.imutools", root / "imutools")):
        shell = types.ModuleType(name)
        shell.__path__ = [str(path)]
        sys.modules[name] = shell
    core = types.ModuleType("skdiveMove.core")
    core.robjs = core.cv = core.pandas2ri = core.diveMove = None
    sys.modules["skdiveMove.core"] = core
    from skdiveMove.imutools.imucalibrate import IMUcalibrate

    return IMUcalibrate


def main() -> None:
    path, out = sys.argv[1:3]
    imucalibrate = _import_peer()
    periods = [slice(a, b) for a, b in PERIODS]
    result = {"periods": PERIODS, "win_len": WIN_LEN, "models": []}
    for t_brk in (None, 10.0):
        for var, use_axis_order in CALLS.items():
            cal = imucalibrate.read_netcdf(
                path, periods=periods, axis_order=list("zxy"), time_name="timestamp_utc",
                has_depth=True,
            )  # fmt: skip
            per = cal.build_tmodels(
                var, T_brk=t_brk, use_axis_order=use_axis_order, win_len=WIN_LEN
            )
            for p, (models, frame) in enumerate(per):
                for axis, fit in models[var].items():
                    if fit is None:
                        continue
                    ref = [c for c in frame[axis].columns if c.startswith(f"{var}_") and
                           c.endswith("C")]  # fmt: skip
                    result["models"].append({
                        "var": var, "period": p, "axis": axis, "t_brk": t_brk,
                        "use_axis_order": use_axis_order, "params": fit.params.tolist(),
                        "param_names": list(fit.params.index), "bse": fit.bse.tolist(),
                        "nobs": int(fit.nobs), "rsquared": float(fit.rsquared),
                        "t_alpha_column": ref[0], "at_t_alpha": float(frame[axis][ref[0]].iloc[0]),
                    })  # fmt: skip
    import skdiveMove.imutools.imucalibrate as module

    result["peer_module"] = str(Path(module.__file__).name)
    result["versions"] = {
        m: sys.modules[m].__version__ for m in ("numpy", "pandas", "statsmodels", "xarray")
    }
    Path(out).write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
