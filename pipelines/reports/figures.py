"""The report's plotly figures, one function per figure.

Conventions: time axes in the hoist's local time with the zone in the axis title;
thresholds and limits are dashed lines that appear in the legend with their value;
"before" is the uncompensated ``p x A`` (grey), "after" the compensated value (blue);
rope i has the same colour in every figure (:mod:`pipelines.reports.figure_style`).
This module draws a hoist-period's series and summaries; the checks and trends are
:mod:`pipelines.reports.check_figures`.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence

import numpy as np
import plotly.graph_objects as go
import polars as pl
from plotly.subplots import make_subplots

from pipelines.reports.data import Zone
from pipelines.reports.figure_style import (
    AFTER,
    BAND,
    BEFORE,
    EXPECTED,
    ROPE_COLOURS,
    RULE_COLOURS,
    WARN,
    layout,
    limit_line,
    symmetric_range,
)
from pipelines.reports.series import PeriodSeries
from transforms.alarms import RuleThresholds

__all__ = [
    "alarm_timeline",
    "load_figure",
    "peak_text",
    "reconciliation_figure",
    "ropes_figure",
    "trips_figure",
]


def _line(
    series: PeriodSeries, key: str, name: str, colour: str, width: float = 1.2, **kw: object
) -> go.Scatter | None:
    if key not in series.lines:
        return None
    t, y = series.lines[key]
    if not np.isfinite(y).any():
        return None
    return go.Scatter(
        x=t, y=y, mode="lines", name=name, line={"color": colour, "width": width}, **kw
    )


def _span(zone: Zone, start: dt.datetime, end: dt.datetime) -> list[dt.datetime]:
    return [zone.local(start).replace(tzinfo=None), zone.local(end).replace(tzinfo=None)]


def load_figure(
    series: PeriodSeries,
    *,
    zone: Zone,
    tolerance_fraction: float,
    visits: pl.DataFrame,
    title: str,
) -> go.Figure:
    """Load before / after (with the 95 % band if landed) and the expected load; below,
    the load error against the expected load during the steady phases of trips."""
    span = _span(zone, *series.span_utc)
    fig = make_subplots(
        rows=2,
        cols=1,
        shared_xaxes=True,
        vertical_spacing=0.08,
        row_heights=[0.62, 0.38],
        subplot_titles=(
            "",
            "load minus expected load, steady phases of trips [% of expected]",
        ),
    )
    if series.band is not None:
        t, lo, hi = series.band
        fig.add_trace(
            go.Scatter(x=t, y=lo, mode="lines", line={"width": 0}, showlegend=False,
                       hoverinfo="skip", legendgroup="band"),
            row=1, col=1,
        )  # fmt: skip
        fig.add_trace(
            go.Scatter(x=t, y=hi, mode="lines", line={"width": 0}, fill="tonexty",
                       fillcolor=BAND, name="95 % band (after)", legendgroup="band"),
            row=1, col=1,
        )  # fmt: skip
    for trace in (
        _line(series, "before_kn", "before (p x A)", BEFORE),
        _line(series, "after_kn", "after compensation", AFTER),
        _line(series, "expected_kn", "expected, in trips", EXPECTED, 1.0, opacity=0.8),
    ):  # fmt: skip
        if trace is not None:
            if trace.name and trace.name.startswith("expected"):
                trace.line.dash = "dot"
            fig.add_trace(trace, row=1, col=1)
    if visits.height:
        fig.add_trace(
            go.Scatter(
                x=visits["mid_local"],
                y=visits["expected_load_n"] / 1e3,
                mode="markers",
                marker={"symbol": "diamond-open", "size": 9, "color": EXPECTED},
                name="expected at position visits",
                text=visits["position"],
                hovertemplate="%{text}: expected %{y:.2f} kN<extra></extra>",
            ),
            row=1,
            col=1,
        )
    for key, name, colour in (
        ("error_before_pct", "error before", BEFORE),
        ("error_after_pct", "error after", AFTER),
    ):
        trace = _line(series, key, name, colour, 1.0, showlegend=False)
        if trace is not None:
            fig.add_trace(trace, row=2, col=1)
    tol = tolerance_fraction * 100
    limit_line(fig, span, tol, f"tolerance +-{tol:g} %", row=2, col=1)
    limit_line(fig, span, -tol, f"tolerance +-{tol:g} %", row=2, col=1, legend=False)
    fig.update_yaxes(title_text="load on the four ropes [kN]", row=1, col=1)
    fig.update_yaxes(title_text="% of expected", row=2, col=1)
    fig.update_xaxes(range=span)
    fig.update_xaxes(title_text=zone.axis_title(*series.span_utc), row=2, col=1)
    if series.band is None:
        title += " (no uncertainty band yet)"
    return layout(fig, title, 620)


def ropes_figure(
    series: PeriodSeries, *, zone: Zone, thresholds: RuleThresholds, title: str
) -> go.Figure:
    """Each rope's deviation from the mean of the four with the imbalance limit; below,
    the lowest and highest of the four tensions with the slack and tight-rope limits."""
    span = _span(zone, *series.span_utc)
    limit = thresholds.imbalance_fraction * 100
    fig = make_subplots(
        rows=2,
        cols=1,
        shared_xaxes=True,
        vertical_spacing=0.08,
        row_heights=[0.55, 0.45],
        subplot_titles=("", "lowest and highest of the four rope tensions [kN]"),
    )
    for rope, colour in ROPE_COLOURS.items():
        trace = _line(series, f"deviation{rope}_pct", f"rope {rope}", colour, 1.0)
        if trace is not None:
            fig.add_trace(trace, row=1, col=1)
    limit_line(fig, span, limit, f"imbalance limit +-{limit:g} %", row=1, col=1)
    limit_line(fig, span, -limit, f"imbalance limit +-{limit:g} %", row=1, col=1, legend=False)
    for key, name, colour in (
        ("highest_kn", "highest rope", "#444444"),
        ("lowest_kn", "lowest rope", "#9a9a9a"),
    ):
        trace = _line(series, key, name, colour, 1.0)
        if trace is not None:
            fig.add_trace(trace, row=2, col=1)
    limit_line(fig, span, thresholds.tight_n / 1e3, f"tight rope {thresholds.tight_n / 1e3:.1f} kN",
           row=2, col=1)  # fmt: skip
    limit_line(fig, span, thresholds.slack_n / 1e3, f"slack rope {thresholds.slack_n / 1e3:.1f} kN",
           row=2, col=1, colour=WARN)  # fmt: skip
    deviation = max(
        (abs(series.extremes.get(f"deviation{r}_pct_{e}", 0.0)) for r in ROPE_COLOURS
         for e in ("min", "max")),
        default=0.0,
    )  # fmt: skip
    symmetric_range(fig, deviation, limit, row=1, what="imbalance limit")
    fig.update_yaxes(title_text="rope minus mean of four [%]", row=1, col=1)
    fig.update_yaxes(title_text="kN", rangemode="tozero", row=2, col=1)
    fig.update_xaxes(range=span)
    fig.update_xaxes(title_text=zone.axis_title(*series.span_utc), row=2, col=1)
    return layout(fig, title, 600)


def peak_text(value: float | None, unit: str | None) -> str:
    if value is None or not np.isfinite(value):
        return ""
    match unit:
        case "1":
            return f"{value * 100:.2f} %"
        case "N":
            return f"{value / 1e3:.2f} kN"
        case "Pa":
            return f"{value / 1e6:.3f} MPa"
        case "s":
            return f"{value:.2f} s"
    return f"{value:.4g} {unit or ''}".strip()


def alarm_timeline(
    alarms: pl.DataFrame, *, zone: Zone, start: dt.datetime, end: dt.datetime, title: str
) -> go.Figure:
    """One row per rope (and one for the hoist-wide rules): a bar from start to end per
    alarm, a marker at its peak; hover for rule, peak and threshold."""
    span = _span(zone, start, end)
    frame = alarms.with_columns(
        zone.expr("start_utc").alias("start_local"),
        zone.expr("end_utc").alias("end_local"),
        zone.expr("peak_time_utc").alias("peak_local"),
        pl.when(pl.col("rope").is_null())
        .then(pl.lit("hoist"))
        .otherwise(pl.format("rope {}", pl.col("rope")))
        .alias("lane"),
    )
    lanes = ["hoist", *[f"rope {r}" for r in sorted(ROPE_COLOURS, reverse=True)]]
    fig = go.Figure()
    rules = sorted(frame["rule"].unique().to_list())
    for k, rule in enumerate(rules):
        colour = RULE_COLOURS[k % len(RULE_COLOURS)]
        part = frame.filter(pl.col("rule") == rule)
        xs: list[object] = []
        ys: list[object] = []
        for row in part.iter_rows(named=True):
            xs += [row["start_local"], row["end_local"], None]
            ys += [row["lane"], row["lane"], None]
        fig.add_trace(
            go.Scatter(x=xs, y=ys, mode="lines", line={"color": colour, "width": 12},
                       name=rule, legendgroup=rule, hoverinfo="skip")
        )  # fmt: skip
        texts = [
            f"{row['rule']} {row['lane']}<br>{zone.text(row['start_utc'])} .. "
            f"{zone.text(row['end_utc'], '%H:%M:%S')}<br>peak "
            f"{peak_text(row['peak_value'], row['unit'])} (limit "
            f"{peak_text(row['threshold'], row['unit'])})"
            for row in part.iter_rows(named=True)
        ]
        fig.add_trace(
            go.Scatter(
                x=part["peak_local"].fill_null(part["start_local"]),
                y=part["lane"],
                mode="markers",
                marker={"color": colour, "size": 11, "symbol": "diamond",
                        "line": {"color": "#222", "width": 1}},
                name=rule,
                legendgroup=rule,
                showlegend=False,
                text=texts,
                hovertemplate="%{text}<extra></extra>",
            )
        )  # fmt: skip
    fig.update_yaxes(categoryorder="array", categoryarray=lanes, range=[-0.6, len(lanes) - 0.4])
    fig.update_xaxes(range=span, title_text=zone.axis_title(start, end))
    return layout(fig, title, 330)


def reconciliation_figure(
    visits: pl.DataFrame,
    *,
    zone: Zone,
    tolerance_fraction: float,
    positions: Sequence[str],
    start: dt.datetime,
    end: dt.datetime,
    title: str,
) -> go.Figure:
    """Per position, the load error of every visit before and after compensation, with
    the tolerance lines."""
    span = _span(zone, start, end)
    fig = make_subplots(
        rows=1,
        cols=len(positions),
        shared_yaxes=True,
        horizontal_spacing=0.03,
        subplot_titles=[f"{p}" for p in positions],
    )
    tol = tolerance_fraction * 100
    for k, position in enumerate(positions, start=1):
        part = visits.filter(pl.col("position") == position)
        for column, name, colour, symbol in (
            ("error_before_pct", "before compensation", BEFORE, "circle-open"),
            ("error_after_pct", "after compensation", AFTER, "circle"),
        ):
            fig.add_trace(
                go.Scatter(
                    x=part["mid_local"],
                    y=part[column],
                    mode="markers",
                    marker={"color": colour, "size": 8, "symbol": symbol},
                    name=name,
                    legendgroup=name,
                    showlegend=k == 1,
                    text=part["label"],
                    hovertemplate="%{text}: %{y:.2f} %<extra>" + name + "</extra>",
                ),
                row=1,
                col=k,
            )
        limit_line(fig, span, tol, f"tolerance +-{tol:g} %", row=1, col=k, legend=k == 1,
               group="tolerance")  # fmt: skip
        limit_line(fig, span, -tol, "tolerance", row=1, col=k, legend=False, group="tolerance")
        fig.update_xaxes(range=span, row=1, col=k, tickformat="%H:%M")
    fig.update_yaxes(title_text="load minus expected [% of expected]", row=1, col=1)
    fig.update_xaxes(title_text=zone.axis_title(start, end), row=1, col=(len(positions) + 1) // 2)
    return layout(fig, title, 400)


def trips_figure(trips: pl.DataFrame, *, imbalance_fraction: float, title: str) -> go.Figure:
    """Worst imbalance per trip, coloured by the rope it was on, with the limit."""
    fig = go.Figure()
    labels = trips["label"].to_list()
    for rope, colour in ROPE_COLOURS.items():
        part = trips.filter(pl.col("worst_rope") == rope)
        if part.height:
            fig.add_trace(
                go.Bar(x=part["label"], y=part["worst_pct"], name=f"rope {rope}",
                       marker_color=colour, width=0.5, hovertemplate="%{x}: %{y:.2f} %<extra>"
                       f"rope {rope}</extra>")
            )  # fmt: skip
    limit = imbalance_fraction * 100
    if labels:
        limit_line(fig, labels, limit, f"imbalance limit {limit:g} %")
    worst = float(trips["worst_pct"].max() or 0.0)
    symmetric_range(fig, worst, limit, what="imbalance limit")
    fig.update_yaxes(range=[0, fig.layout.yaxis.range[1]])
    fig.update_xaxes(categoryorder="array", categoryarray=labels, title_text="trip")
    fig.update_yaxes(title_text="worst |rope - mean| [% of mean]")
    return layout(fig, title, 360)
