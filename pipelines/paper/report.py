"""The shape of a ``ropeload paper`` section: rows of paper vs ropeload, notes, a figure.

:class:`Row` -- one number the paper prints (or implies) beside ropeload's.
:class:`PaperSection` -- a section's rows, its notes and the files it wrote.
:func:`format_section` -- the printed table.
:func:`new_figure`, :func:`save_figure` -- matplotlib figures without pyplot (Agg
canvas, no global state, no display needed), saved as PNG.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl

__all__ = ["PaperSection", "Row", "format_section", "new_figure", "save_figure"]


@dataclass(frozen=True)
class Row:
    """One compared quantity.

    ``paper`` is the paper's number (printed, or its formula evaluated; ``None`` when
    the paper gives none), ``ropeload`` ropeload's, both in ``unit``; ``fmt`` the
    format spec of both; ``note`` where each number comes from.
    """

    quantity: str
    unit: str
    paper: float | None
    ropeload: float
    fmt: str = ".4g"
    note: str = ""

    @property
    def difference(self) -> float | None:
        """ropeload - paper, or None without a paper number."""
        return None if self.paper is None else self.ropeload - self.paper

    @property
    def relative(self) -> float | None:
        """(ropeload - paper) / |paper|, or None (no paper number, or it is 0)."""
        if self.paper is None or self.paper == 0:
            return None
        return (self.ropeload - self.paper) / abs(self.paper)


@dataclass
class PaperSection:
    """A reproduced part of the paper: ``key`` (the subcommand), ``title``, ``intro``
    paragraphs (what was computed and with which constants), ``rows``, ``notes``
    (paragraphs: verdicts, errata; leading spaces indent), and the ``files`` written
    (figure, rows as CSV)."""

    key: str
    title: str
    intro: list[str] = field(default_factory=list)
    rows: list[Row] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)

    def frame(self) -> pl.DataFrame:
        """The rows as a table (what is written as ``<key>.csv``)."""
        return pl.DataFrame(
            {
                "quantity": [r.quantity for r in self.rows],
                "unit": [r.unit for r in self.rows],
                "paper": [r.paper for r in self.rows],
                "ropeload": [r.ropeload for r in self.rows],
                "difference": [r.difference for r in self.rows],
                "note": [r.note for r in self.rows],
            },
            schema={
                "quantity": pl.String,
                "unit": pl.String,
                "paper": pl.Float64,
                "ropeload": pl.Float64,
                "difference": pl.Float64,
                "note": pl.String,
            },
        )

    def write_rows(self, out_dir: Path) -> Path:
        path = out_dir / f"{self.key}.csv"
        self.frame().write_csv(path)
        self.files.append(path)
        return path


def _number(value: float | None, fmt: str, *, sign: bool = False) -> str:
    if value is None:
        return "-"
    if not math.isfinite(value):
        return str(value)
    spec = ("+" if sign else "") + fmt
    return format(value, spec)


#: Width the intro and notes paragraphs are wrapped to.
WIDTH = 100


def _paragraph(text: str) -> list[str]:
    lead = text[: len(text) - len(text.lstrip())]
    return textwrap.wrap(
        text.strip(), WIDTH, initial_indent=lead, subsequent_indent=lead + "  "
    ) or [""]


def format_section(section: PaperSection) -> str:
    """The printed form: title, intro, a table (quantity, unit, paper, ropeload,
    ropeload - paper with the relative difference, note), the notes and the files."""
    head = ("quantity", "unit", "paper", "ropeload", "ropeload - paper", "note")
    body = []
    for r in section.rows:
        diff = _number(r.difference, r.fmt, sign=True)
        if r.relative is not None:
            diff += f" ({100 * r.relative:+.1f} %)"
        body.append(
            (
                r.quantity,
                r.unit,
                _number(r.paper, r.fmt),
                _number(r.ropeload, r.fmt),
                diff,
                r.note,
            )
        )
    widths = [max(len(row[k]) for row in [head, *body]) for k in range(len(head) - 1)]
    align = ("<", "<", ">", ">", ">")

    def line(cells: tuple[str, ...]) -> str:
        parts = [f"{c:{a}{w}}" for c, a, w in zip(cells[:-1], align, widths, strict=True)]
        return ("  ".join(parts) + ("  " + cells[-1] if cells[-1] else "")).rstrip()

    rule = "=" * len(section.title)
    out = [section.title, rule]
    for text in section.intro:
        out += _paragraph(text)
    out.append("")
    out.append(line(head))
    out.append(line((*("-" * w for w in widths), "----")))
    out += [line(cells) for cells in body]
    if section.notes:
        out.append("")
        for text in section.notes:
            out += _paragraph(text)
    for path in section.files:
        out.append(f"{'figure' if path.suffix == '.png' else 'rows'}: {path}")
    return "\n".join(out) + "\n"


def new_figure(width_in: float, height_in: float) -> Any:
    """A matplotlib :class:`~matplotlib.figure.Figure` on an Agg canvas (no pyplot:
    nothing global, nothing shown, safe in threads and without a display)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def save_figure(figure: Any, section: PaperSection, out_dir: Path, *, dpi: int = 150) -> Path:
    """Save ``figure`` as ``<out_dir>/<key>.png`` and record it on the section."""
    path = out_dir / f"{section.key}.png"
    figure.savefig(path, dpi=dpi)
    section.files.append(path)
    return path
