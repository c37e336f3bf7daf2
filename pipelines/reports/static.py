"""Static PNG of a report figure, for Prefect artifacts.

Prefect's UI shows markdown artifacts without running scripts, so an interactive plotly
figure cannot live there. :func:`figure_png` redraws a report figure with matplotlib
(headless Agg, already a dependency) from the figure's own data: the same traces,
limits, titles and axis labels, at a fixed size. It understands what
:mod:`pipelines.reports.figures` and :mod:`pipelines.reports.check_figures` draw (lines,
markers, bands, bars, subplots,
categorical and time axes), not every plotly figure.
"""

from __future__ import annotations

import base64
import datetime as dt
import io
from collections.abc import Sequence
from typing import Any

import numpy as np
import plotly.graph_objects as go

__all__ = ["figure_png"]

_DASH = {"dash": "--", "dot": ":", "dashdot": "-.", "longdash": "--", "solid": "-"}
_MARGIN = {"left": 0.07, "right": 0.78, "bottom": 0.1, "top": 0.86}


def _axis_key(ref: str, prefix: str) -> str:
    """``x2`` -> ``xaxis2``, ``x`` -> ``xaxis``."""
    return f"{prefix}axis{ref[1:]}"


def _domain(layout: go.Layout, key: str) -> tuple[float, float]:
    axis = layout[key] if key in layout else None
    domain = getattr(axis, "domain", None) if axis is not None else None
    return (float(domain[0]), float(domain[1])) if domain else (0.0, 1.0)


def _values(raw: Any) -> np.ndarray:
    """Plotly trace data as numpy: datetimes as ``datetime64[us]`` (None as NaT)."""
    if raw is None:
        return np.zeros(0)
    array = np.asarray(raw)
    if array.dtype.kind == "M":
        return array.astype("datetime64[us]")
    if array.dtype == object:
        items = list(array)
        if any(isinstance(v, dt.datetime | np.datetime64) for v in items):
            return np.array(
                [np.datetime64("NaT") if v is None else np.datetime64(v, "us") for v in items],
                dtype="datetime64[us]",
            )
        if all(v is None or isinstance(v, int | float) for v in items):
            return np.array([np.nan if v is None else v for v in items], dtype=float)
    return array


class _Categories:
    """Category -> position on one axis (``categoryarray`` first, then as met)."""

    def __init__(self, given: Sequence[object] | None) -> None:
        self.index: dict[str, int] = {str(v): k for k, v in enumerate(given or ())}

    def __call__(self, values: np.ndarray) -> np.ndarray:
        out = np.full(values.shape, np.nan)
        for k, v in enumerate(values):
            if v is None:
                continue
            out[k] = self.index.setdefault(str(v), len(self.index))
        return out


def _numeric(values: np.ndarray, categories: _Categories) -> np.ndarray:
    if values.dtype.kind in "USO":
        return categories(values)
    return values


def figure_png(figure: go.Figure, *, dpi: int = 72) -> str | None:
    """``figure`` as a base64 PNG (matplotlib), or None when it has no trace."""
    if not figure.data:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    layout = figure.layout
    height_in = max(3.0, float(layout.height or 450) / 100 * 1.1)
    fig = plt.figure(figsize=(13.0, height_in), dpi=dpi)
    axes: dict[tuple[str, str], Any] = {}
    cats: dict[str, _Categories] = {}
    width = _MARGIN["right"] - _MARGIN["left"]
    tall = _MARGIN["top"] - _MARGIN["bottom"]

    def axes_for(xref: str, yref: str) -> Any:
        if (xref, yref) not in axes:
            x0, x1 = _domain(layout, _axis_key(xref, "x"))
            y0, y1 = _domain(layout, _axis_key(yref, "y"))
            rect = [
                _MARGIN["left"] + x0 * width,
                _MARGIN["bottom"] + y0 * tall,
                (x1 - x0) * width * 0.97,
                (y1 - y0) * tall * 0.86,
            ]
            axes[(xref, yref)] = fig.add_axes(rect)
            for ref, prefix in ((xref, "x"), (yref, "y")):
                key = _axis_key(ref, prefix)
                axis = layout[key] if key in layout else None
                given = getattr(axis, "categoryarray", None) if axis is not None else None
                cats.setdefault(key, _Categories(given))
        return axes[(xref, yref)]

    handles: dict[str, Any] = {}
    previous: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}
    bar_traces = [t for t in figure.data if t.type == "bar"]
    for trace in figure.data:
        xref, yref = trace.xaxis or "x", trace.yaxis or "y"
        ax = axes_for(xref, yref)
        x = _numeric(_values(trace.x), cats[_axis_key(xref, "x")])
        y = _numeric(_values(trace.y), cats[_axis_key(yref, "y")])
        if x.size == 0 or y.size == 0:
            continue
        name = trace.name if trace.showlegend is not False and trace.name else None
        artist = _draw(ax, trace, x, y, previous.get((xref, yref)), bar_traces)
        previous[(xref, yref)] = (x, y)
        if name and artist is not None and name not in handles:
            handles[name] = artist
    for (xref, yref), ax in axes.items():
        _finish_axes(ax, layout, _axis_key(xref, "x"), _axis_key(yref, "y"), cats)
    _annotations(fig, layout, axes)
    title = layout.title.text if layout.title else None
    if title:
        fig.suptitle(str(title), x=0.01, y=0.985, ha="left", fontsize=12)
    if handles:
        fig.legend(
            list(handles.values()),
            list(handles),
            loc="upper left",
            bbox_to_anchor=(_MARGIN["right"] + 0.01, _MARGIN["top"]),
            fontsize=9,
            frameon=False,
        )
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _colour(trace: Any) -> str | None:
    for part in ("line", "marker"):
        colour = getattr(getattr(trace, part, None), "color", None)
        if isinstance(colour, str):
            return colour if not colour.startswith("rgba") else _rgba(colour)
    return None


def _rgba(text: str) -> Any:
    parts = [float(v) for v in text[text.index("(") + 1 : text.index(")")].split(",")]
    return (parts[0] / 255, parts[1] / 255, parts[2] / 255, parts[3] if len(parts) > 3 else 1.0)


def _draw(
    ax: Any,
    trace: Any,
    x: np.ndarray,
    y: np.ndarray,
    previous: tuple[np.ndarray, np.ndarray] | None,
    bars: Sequence[Any],
) -> Any:
    colour = _colour(trace)
    if trace.type == "bar":
        same_axes = [b for b in bars if (b.xaxis, b.yaxis) == (trace.xaxis, trace.yaxis)]
        grouped = len(same_axes) > 1 and (trace.offsetgroup or True)
        k = next(i for i, b in enumerate(same_axes) if b is trace)
        width = float(trace.width or 0.8 / max(1, len(same_axes) if grouped else 1))
        offset = (k - (len(same_axes) - 1) / 2) * width if x.dtype.kind == "f" else 0
        return ax.bar(x + offset if x.dtype.kind == "f" else x, y, width=width, color=colour)
    mode = trace.mode or "lines"
    line = getattr(trace, "line", None)
    if trace.fill == "tonexty" and previous is not None and previous[0].shape == x.shape:
        colour = _rgba(trace.fillcolor) if str(trace.fillcolor).startswith("rgba") else colour
        return ax.fill_between(x, previous[1], y, color=colour, linewidth=0)
    if "lines" in mode and (getattr(line, "width", None) != 0):
        style = _DASH.get(getattr(line, "dash", None) or "solid", "-")
        lw = float(getattr(line, "width", None) or 1.2)
        marker = "o" if "markers" in mode else None
        (artist,) = ax.plot(x, y, style, color=colour, lw=min(lw, 8.0), marker=marker, ms=3)
        return artist
    if "markers" in mode:
        symbol = str(getattr(trace.marker, "symbol", "") or "")
        filled = "open" not in symbol
        marker = "D" if "diamond" in symbol else "_" if "line-ew" in symbol else "o"
        if marker == "_":  # a short horizontal tick per category (noise, limits)
            return ax.scatter(x, y, s=900, marker=marker, color=colour, linewidths=2, zorder=3)
        return ax.scatter(
            x, y, s=22, marker=marker, edgecolors=colour,
            facecolors=colour if filled else "none", zorder=3,
        )  # fmt: skip
    return None


def _finish_axes(ax: Any, layout: go.Layout, xkey: str, ykey: str, cats: dict) -> None:
    for key, set_label, set_lim, set_ticks in (
        (xkey, ax.set_xlabel, ax.set_xlim, ax.set_xticks),
        (ykey, ax.set_ylabel, ax.set_ylim, ax.set_yticks),
    ):
        axis = layout[key] if key in layout else None
        title = getattr(getattr(axis, "title", None), "text", None) if axis else None
        if title:
            set_label(str(title), fontsize=9)
        rng = getattr(axis, "range", None) if axis else None
        if rng and len(rng) == 2 and None not in rng:
            low, high = (_values([v])[0] for v in rng)
            if not (isinstance(low, str) or isinstance(high, str)):
                set_lim(low, high)
        index = cats[key].index
        if index:
            set_ticks(list(index.values()), list(index), fontsize=8)
    ax.tick_params(labelsize=8)
    ax.grid(alpha=0.3)
    import matplotlib.dates as mdates

    if isinstance(ax.xaxis.get_major_formatter(), mdates.AutoDateFormatter):
        locator = mdates.AutoDateLocator(maxticks=7)
        ax.xaxis.set_major_locator(locator)
        ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))


def _annotations(fig: Any, layout: go.Layout, axes: dict) -> None:
    by_domain = {(_axis_key(x, "x"), _axis_key(y, "y")): ax for (x, y), ax in axes.items()}
    width = _MARGIN["right"] - _MARGIN["left"]
    tall = _MARGIN["top"] - _MARGIN["bottom"]
    for note in layout.annotations or ():
        text = str(note.text or "")
        if not text:
            continue
        xref, yref = str(note.xref or "paper"), str(note.yref or "paper")
        if xref == "paper" and yref == "paper":
            fig.text(
                _MARGIN["left"] + float(note.x) * width,
                _MARGIN["bottom"] + float(note.y) * tall * 0.98,
                text, ha="center", va="bottom", fontsize=9,
            )  # fmt: skip
            continue
        xkey = _axis_key(xref.split()[0], "x")
        ykey = _axis_key(yref.split()[0], "y")
        ax = by_domain.get((xkey, ykey))
        if ax is not None:
            ax.text(
                float(note.x), float(note.y), text, transform=ax.transAxes, ha="right",
                va="top", fontsize=8, color=getattr(note.font, "color", None) or "#333",
            )  # fmt: skip
