"""The look shared by the report's figures: colours, layout, limit lines, y ranges.

"before" is the uncompensated ``p x A`` (grey, :data:`BEFORE`), "after" the compensated
value (blue, :data:`AFTER`); rope i has the same colour in every figure
(:data:`ROPE_COLOURS`); limits are dashed lines that appear in the legend with their
value (:func:`limit_line`).
"""

from __future__ import annotations

from collections.abc import Sequence

import plotly.graph_objects as go

__all__ = [
    "AFTER",
    "BAND",
    "BEFORE",
    "EXPECTED",
    "LIMIT",
    "ROPE_COLOURS",
    "RULE_COLOURS",
    "WARN",
    "layout",
    "limit_line",
    "symmetric_range",
]


ROPE_COLOURS = {1: "#1f77b4", 2: "#ff7f0e", 3: "#2ca02c", 4: "#9467bd"}
BEFORE = "#8c8c8c"
AFTER = "#1f4e9c"
EXPECTED = "#111111"
LIMIT = "#d62728"
WARN = "#e69500"
BAND = "rgba(31, 78, 156, 0.18)"
RULE_COLOURS = [
    "#d62728",
    "#e69500",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
    "#7f7f7f",
    "#9467bd",
    "#2ca02c",
]


def layout(fig: go.Figure, title: str, height: int, *, legend: bool = True) -> go.Figure:
    """The report's layout: white template, title on the left, legend on the right."""
    fig.update_layout(
        template="plotly_white",
        title={"text": title, "x": 0.01, "xanchor": "left", "font": {"size": 16}},
        height=height,
        margin={"l": 70, "r": 20, "t": 60, "b": 60},
        font={"size": 12},
        showlegend=legend,
        legend={"orientation": "v", "yanchor": "top", "y": 1.0, "x": 1.01, "xanchor": "left",
                "font": {"size": 11}, "tracegroupgap": 4},
        hovermode="closest",
    )  # fmt: skip
    return fig


def symmetric_range(
    fig: go.Figure, worst: float, limit: float, *, row: int | None = None, what: str
) -> None:
    """A y range that shows the data: up to the limit when the data come near it (at
    least 30 % of it), else around the data, saying that the limit is off the scale."""
    if worst >= 0.3 * limit:
        top = 1.15 * max(limit, worst)
    else:
        top = max(1.3 * worst, 0.05 * limit)
        fig.add_annotation(
            text=f"the {what} (+-{limit:g} %) is off this scale: largest {worst:.2f} %",
            xref="x domain" if row in (None, 1) else f"x{row} domain",
            yref="y domain" if row in (None, 1) else f"y{row} domain",
            x=0.995, y=0.98, xanchor="right", yanchor="top", showarrow=False,
            font={"size": 11, "color": LIMIT}, bgcolor="rgba(255,255,255,0.8)",
        )  # fmt: skip
    if row is None:
        fig.update_yaxes(range=[-top, top])
    else:
        fig.update_yaxes(range=[-top, top], row=row, col=1)


def limit_line(
    fig: go.Figure,
    x: Sequence[object],
    y: float,
    name: str,
    *,
    row: int | None = None,
    col: int | None = None,
    colour: str = LIMIT,
    legend: bool = True,
    group: str | None = None,
) -> None:
    """A dashed horizontal limit line over ``x[0] .. x[-1]`` that shows in the legend."""
    trace = go.Scatter(
        x=[x[0], x[-1]],
        y=[y, y],
        mode="lines",
        line={"color": colour, "dash": "dash", "width": 1.5},
        name=name,
        legendgroup=group or name,
        showlegend=legend,
        hoverinfo="name+y",
    )
    if row is None:
        fig.add_trace(trace)
    else:
        fig.add_trace(trace, row=row, col=col or 1)
