"""The fleet report: a self-contained HTML page of a sample sheet's calibrations."""

from __future__ import annotations

from collections.abc import Mapping

import jinja2


def render_fleet_report(summary: Mapping, figures: Mapping[str, str]) -> str:
    """The fleet report (HTML with the figures embedded).

    Parameters
    ----------
    summary : dict
        ``fleet.json`` of the ``fleet`` rule: ``sheet``, ``store``, ``imucal_version``,
        ``n_units``, ``n_sessions``, ``outlier_z``, ``outlier_note``, ``outliers`` (rows of
        :func:`imucal.fleet.flag_outliers` flagged), ``drift_z``, ``drift`` (rows of
        :func:`imucal.fleet.drift_table` beyond it), ``store_index``.
    figures : dict of str to str
        ``parameters`` and ``drift``: ``data:`` URIs (:func:`imucal.report.embed_figure`).

    Returns
    -------
    str
    """
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("imucal.report", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
    )
    return env.get_template("fleet.html.j2").render(**summary, figures=figures)
