"""The report's figures of its checks and trends, one function per figure.

The simulation sanity check (:func:`sanity_figure`), the discovery findings
(:func:`discovery_regions_figure`, :func:`discovery_trace_figure`) and a backfill's day
by day trend (:func:`trend_figure`); conventions of :mod:`pipelines.reports.figures`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import plotly.graph_objects as go
import polars as pl
from plotly.subplots import make_subplots

from pipelines.reports.figure_style import (
    AFTER,
    BEFORE,
    LIMIT,
    WARN,
    layout,
    limit_line,
    symmetric_range,
)

__all__ = [
    "discovery_regions_figure",
    "discovery_trace_figure",
    "sanity_figure",
    "trend_figure",
]


def sanity_figure(checks: pl.DataFrame, *, title: str) -> go.Figure:
    """RMS of measured minus simulated sensor pressure per trip, and its pass limit."""
    fig = go.Figure()
    for status, name, colour in (("passed", "passed", "#2ca02c"), ("failed", "failed", LIMIT)):
        part = checks.filter(pl.col("status") == status)
        if part.height:
            fig.add_trace(
                go.Bar(x=part["label"], y=part["rms_gap_pa"] / 1e3, name=f"trip {name}",
                       marker_color=colour, width=0.5,
                       hovertemplate="%{x}: %{y:.2f} kPa<extra></extra>")
            )  # fmt: skip
    fig.add_trace(
        go.Scatter(x=checks["label"], y=checks["noise_pa"] / 1e3, mode="markers",
                   marker={"symbol": "line-ew-open", "size": 30, "color": "#333"},
                   name="sensor noise (estimated)")
    )  # fmt: skip
    if checks["limit_pa"].is_not_null().any():
        fig.add_trace(
            go.Scatter(x=checks["label"], y=checks["limit_pa"] / 1e3, mode="markers",
                       marker={"symbol": "line-ew-open", "size": 30, "color": LIMIT,
                               "line": {"width": 2}},
                       name="pass limit")
        )  # fmt: skip
    fig.update_xaxes(categoryorder="array", categoryarray=checks["label"].to_list())
    fig.update_yaxes(title_text="RMS of measured - simulated [kPa]", rangemode="tozero")
    return layout(fig, title, 360)


def discovery_regions_figure(
    regions: Sequence[dict[str, object]],
    *,
    noise_pa: float | None,
    effect: str | None,
    title: str,
) -> go.Figure:
    """RMS gap per regime before and after one iteration's effect (``None``: none added)."""
    labels = [str(r.get("regime", "?")) for r in regions]
    before = [float(r.get("gap_pa") or np.nan) / 1e3 for r in regions]  # type: ignore[arg-type]
    after = [
        float(r.get("gap_after_pa") or r.get("gap_pa") or np.nan) / 1e3  # type: ignore[arg-type]
        for r in regions
    ]
    bars = [go.Bar(x=labels, y=before, name="before this iteration", marker_color=BEFORE)]
    if effect is not None:
        bars.append(go.Bar(x=labels, y=after, name=f"after adding {effect}", marker_color=AFTER))
    fig = go.Figure(bars)
    if noise_pa and labels:
        limit_line(fig, labels, noise_pa / 1e3, f"sensor noise {noise_pa / 1e3:.1f} kPa",
               colour="#333")  # fmt: skip
    fig.update_layout(barmode="group")
    fig.update_yaxes(title_text="RMS of measured - simulated [kPa]", rangemode="tozero")
    return layout(fig, title, 360)


def discovery_trace_figure(trace: dict[str, object], *, title: str) -> go.Figure:
    """The worst trip's residual over time, before and after the effects found."""
    fig = go.Figure()
    for key, name, colour in (
        ("before", "before (the hoist's model)", BEFORE),
        ("after", "after adding the effects found", AFTER),
    ):
        part = trace.get(key)
        if not isinstance(part, dict):
            continue
        t = np.asarray(part.get("time_s", []), dtype=float)
        y = np.array([np.nan if v is None else v for v in part.get("pa", [])], dtype=float)
        if y.size == t.size and y.size:
            fig.add_trace(go.Scatter(x=t, y=y / 1e3, mode="lines", name=name,
                                     line={"color": colour, "width": 1.2}))  # fmt: skip
    fig.update_xaxes(title_text="time since the trip started [s]")
    fig.update_yaxes(title_text="measured - simulated [kPa]")
    return layout(fig, title, 360)


def trend_figure(
    daily: pl.DataFrame, *, imbalance_fraction: float, tolerance_fraction: float, title: str
) -> go.Figure:
    """Day by day over a backfill: worst load error before / after, worst imbalance,
    alarms. ``daily`` has ``day`` and the columns below (null where a day had none)."""
    fig = make_subplots(
        rows=3,
        cols=1,
        shared_xaxes=True,
        vertical_spacing=0.07,
        subplot_titles=(
            "worst |load minus expected| of the day's position visits [%]",
            "",
            "alarms per day",
        ),
    )
    days = daily["day"].to_list()
    if not days:
        return layout(fig, title, 300)
    for column, name, colour in (
        ("worst_error_before_pct", "before compensation", BEFORE),
        ("worst_error_after_pct", "after compensation", AFTER),
    ):
        fig.add_trace(
            go.Scatter(x=days, y=daily[column], mode="lines+markers", name=name,
                       line={"color": colour}),
            row=1, col=1,
        )  # fmt: skip
    limit_line(fig, days, tolerance_fraction * 100, f"tolerance {tolerance_fraction * 100:g} %",
           row=1, col=1)  # fmt: skip
    fig.add_trace(
        go.Scatter(x=days, y=daily["worst_imbalance_pct"], mode="lines+markers",
                   name="worst imbalance", line={"color": "#444"}),
        row=2, col=1,
    )  # fmt: skip
    fig.update_yaxes(title_text="worst imbalance [%]", row=2, col=1)
    fig.update_yaxes(rangemode="tozero", row=3, col=1)
    limit = imbalance_fraction * 100
    limit_line(fig, days, limit, f"imbalance limit {limit:g} %", row=2, col=1)
    symmetric_range(fig, float(daily["worst_imbalance_pct"].max() or 0.0), limit, row=2,
                     what="imbalance limit")  # fmt: skip
    fig.update_yaxes(range=[0, fig.layout.yaxis2.range[1]], row=2, col=1)
    fig.add_trace(go.Bar(x=days, y=daily["alarms"], name="alarms", marker_color=WARN),
                  row=3, col=1)  # fmt: skip
    fig.update_xaxes(
        type="date", tickformat="%Y-%m-%d", dtick=86_400_000.0 * max(1, len(days) // 12)
    )
    fig.update_xaxes(title_text="day (UTC, as the backfill's hoist-days)", row=3, col=1)
    return layout(fig, title, 640)
