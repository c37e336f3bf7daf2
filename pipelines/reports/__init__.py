"""Reports people read: one self-contained, interactive HTML file per command that computes.

``ropeload run``, ``ropeload demo`` (one run), ``ropeload nightly`` (one per night, every
hoist-day it processed) and ``ropeload backfill`` (one per run of the command) each write
one HTML file under ``<data>/reports/`` and print its path; their Prefect flows publish
the same content as artifacts (:meth:`Report.markdown`: sentences and tables, figures as
static PNG, the HTML's path).

What a hoist-period shows, in the hoist's local time (``[hoist] timezone``, named on
every time axis): the load before (``p x A``) and after compensation with the 95 % band
when landed and the expected load; each rope's deviation from the mean of the four with
the imbalance limit, the lowest and highest rope tension with the slack and tight-rope
limits; the alarms as a timeline and a table (rope, start, end, peak); the
reconciliation per position visit with the tolerance line; the trips (direction,
payload, worst imbalance and its rope); the sanity check and the discovery findings
with their residual plots; and, in words, every step that failed or was skipped.

Modules: :mod:`~pipelines.reports.downsample` (min/max per pixel bucket),
:mod:`~pipelines.reports.data` (what is read from the warehouse),
:mod:`~pipelines.reports.series` (what is read from the lake),
:mod:`~pipelines.reports.figures`, :mod:`~pipelines.reports.check_figures` and
:mod:`~pipelines.reports.figure_style` (plotly), :mod:`~pipelines.reports.sections` (one
hoist-period: :mod:`~pipelines.reports.period`,
:mod:`~pipelines.reports.series_sections`, :mod:`~pipelines.reports.check_sections`),
:mod:`~pipelines.reports.build` and :mod:`~pipelines.reports.fleet` (per command),
:mod:`~pipelines.reports.document` (HTML / markdown), :mod:`~pipelines.reports.static`
(PNG for artifacts).

Only the downsampling is imported eagerly; the rest (plotly) on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from pipelines.reports.downsample import bucket_extremes, downsample_minmax

if TYPE_CHECKING:
    from pipelines.reports.build import (
        run_report,
        run_report_path,
        sanity_step,
        write_fleet_report,
        write_report,
        write_run_report,
    )
    from pipelines.reports.document import Report, Section, Table
    from pipelines.reports.fleet import fleet_report
    from pipelines.reports.period import HoistPeriod, Step
    from pipelines.reports.static import figure_png

__all__ = [
    "HoistPeriod",
    "Report",
    "Section",
    "Step",
    "Table",
    "bucket_extremes",
    "downsample_minmax",
    "figure_png",
    "fleet_report",
    "run_report",
    "run_report_path",
    "sanity_step",
    "write_fleet_report",
    "write_report",
    "write_run_report",
]

_LAZY = {
    "fleet_report": "fleet",
    "run_report": "build",
    "sanity_step": "build",
    "write_report": "build",
    "write_fleet_report": "build",
    "write_run_report": "build",
    "run_report_path": "build",
    "Report": "document",
    "Section": "document",
    "Table": "document",
    "HoistPeriod": "period",
    "Step": "period",
    "figure_png": "static",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'pipelines.reports' has no attribute {name!r}")
    from importlib import import_module

    value = getattr(import_module(f"pipelines.reports.{module}"), name)
    globals()[name] = value
    return value
