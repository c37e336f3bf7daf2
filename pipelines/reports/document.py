"""A report as a document: sections of sentences, tables and figures; HTML and markdown.

:class:`Report` renders to

* one self-contained HTML file (:meth:`Report.html`): the plotly.js library inlined
  once in the page head, each figure a ``<div>`` with its data; no request leaves the
  file when it is opened (no CDN, no fonts, no MathJax);
* markdown for a Prefect artifact (:meth:`Report.markdown`): the same sentences and
  tables, figures as static PNG (``data:`` URIs) when given, and the HTML file's path.
"""

from __future__ import annotations

import datetime as dt
import html
import re
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Literal

import plotly.graph_objects as go

__all__ = ["Note", "Report", "Section", "Table", "stamped_stem"]

Level = Literal["info", "ok", "warn", "fail"]
_MD_ROWS = 30


@dataclass(frozen=True)
class Note:
    """A sentence; ``level`` colours it (``fail``: a step failed; ``warn``: look at it)."""

    text: str
    level: Level = "info"


@dataclass
class Table:
    """A table of already formatted cells; ``key`` names its Prefect table artifact."""

    title: str
    columns: list[str]
    rows: list[list[str]]
    note: str = ""
    key: str | None = None
    limit: int = 500

    def records(self) -> list[dict[str, str]]:
        return [dict(zip(self.columns, row, strict=True)) for row in self.rows[: self.limit]]

    def html(self) -> str:
        head = "".join(f"<th>{html.escape(c)}</th>" for c in self.columns)
        body = "\n".join(
            "<tr>" + "".join(_cell(v) for v in row) + "</tr>" for row in self.rows[: self.limit]
        )
        more = (
            f"<p class='note'>{len(self.rows) - self.limit} more rows not shown "
            "(all are in the warehouse: ropeload query)</p>"
            if len(self.rows) > self.limit
            else ""
        )
        note = f"<p class='note'>{html.escape(self.note)}</p>" if self.note else ""
        title = f"<h4>{html.escape(self.title)}</h4>" if self.title else ""
        return (
            f"{title}<div class='table'><table><thead><tr>{head}</tr></thead>"
            f"<tbody>\n{body}\n</tbody></table></div>{more}{note}"
        )

    def markdown(self) -> str:
        def cell(v: str) -> str:
            return v.replace("|", "/").replace("\n", " ")

        lines = [f"**{self.title}**\n"] if self.title else []
        if not self.rows:
            return "\n".join([*lines, "_none_\n"])
        lines.append("| " + " | ".join(map(cell, self.columns)) + " |")
        lines.append("|" + "---|" * len(self.columns))
        lines += ["| " + " | ".join(map(cell, r)) + " |" for r in self.rows[:_MD_ROWS]]
        if len(self.rows) > _MD_ROWS:
            lines.append(f"\n_{len(self.rows) - _MD_ROWS} more rows: see the HTML report_")
        if self.note:
            lines.append(f"\n_{self.note}_")
        return "\n".join(lines) + "\n"


@dataclass
class Section:
    """A heading with sentences, figures and tables, in that order; ``level`` 2 or 3."""

    title: str
    level: int = 2
    notes: list[Note] = field(default_factory=list)
    figures: list[go.Figure] = field(default_factory=list)
    tables: list[Table] = field(default_factory=list)
    anchor: str = ""

    def say(self, text: str, level: Level = "info") -> Section:
        self.notes.append(Note(text, level))
        return self


def stamped_stem(kind: str, stamp: dt.datetime) -> str:
    """``<kind>-<UTC stamp>-<6 hex>``: the file stem of a report not named by a run (a
    night, a backfill, a fallback); the random hex digits keep two started in the same
    second apart."""
    return f"{kind}-{stamp:%Y%m%dT%H%M%SZ}-{uuid.uuid4().hex[:6]}"


@dataclass
class Report:
    """A report: title, a few lines about what it covers, and sections."""

    title: str
    file_name: str
    about: list[str] = field(default_factory=list)
    sections: list[Section] = field(default_factory=list)
    created_utc: dt.datetime = field(default_factory=lambda: dt.datetime.now(dt.UTC))
    path: Path | None = None

    @property
    def tables(self) -> dict[str, list[dict[str, str]]]:
        """Tables with a ``key``, as rows for Prefect table artifacts."""
        out: dict[str, list[dict[str, str]]] = {}
        for section in self.sections:
            for table in section.tables:
                if table.key:
                    out.setdefault(table.key, []).extend(table.records())
        return out

    @property
    def figure_count(self) -> int:
        return sum(len(s.figures) for s in self.sections)

    def html(self) -> str:
        """The whole report as one self-contained HTML page."""
        toc = "".join(
            f"<li><a href='#{s.anchor}'>{html.escape(s.title)}</a></li>"
            for s in self.sections
            if s.level == 2 and s.anchor
        )
        parts = [
            "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
            f"<title>{html.escape(self.title)}</title>",
            f"<style>{_CSS}</style>",
            f"<script type='text/javascript'>{_plotly_js()}</script>",
            "</head><body><main>",
            f"<h1>{html.escape(self.title)}</h1>",
            "<ul class='about'>",
            *[f"<li>{html.escape(line)}</li>" for line in self.about],
            f"<li>written {self.created_utc:%Y-%m-%d %H:%M:%S} UTC</li></ul>",
            f"<nav><ul>{toc}</ul></nav>" if toc else "",
        ]
        for section in self.sections:
            level = min(max(section.level, 2), 4)
            anchor = f" id='{section.anchor}'" if section.anchor else ""
            parts.append(f"<section><h{level}{anchor}>{html.escape(section.title)}</h{level}>")
            parts += [f"<p class='{n.level}'>{html.escape(n.text)}</p>" for n in section.notes]
            parts += [_figure_html(f) for f in section.figures]
            parts += [t.html() for t in section.tables]
            parts.append("</section>")
        parts.append("</main></body></html>")
        return "\n".join(parts)

    def markdown(
        self,
        png: Callable[[go.Figure], str | None] | None = None,
        *,
        max_figures: int = 24,
    ) -> str:
        """Markdown for a Prefect artifact; ``png(figure)`` gives a base64 PNG or None."""
        marks = {"fail": "**FAILED:** ", "warn": "**Note:** ", "ok": "", "info": ""}
        lines = [f"# {self.title}\n", *[f"- {line}" for line in self.about], ""]
        drawn = 0
        for section in self.sections:
            lines.append(f"{'#' * min(max(section.level, 2), 4)} {section.title}\n")
            lines += [f"{marks[n.level]}{n.text}\n" for n in section.notes]
            for figure in section.figures:
                title = _figure_title(figure)
                encoded = png(figure) if png is not None and drawn < max_figures else None
                if encoded:
                    drawn += 1
                    lines.append(f"![{title}](data:image/png;base64,{encoded})\n")
                else:
                    lines.append(f"_Figure: {title} (interactive, in the HTML report)_\n")
            lines += [t.markdown() for t in section.tables]
        if self.path is not None:
            lines.append(f"\nHTML report (interactive figures): `{self.path}`\n")
        return "\n".join(lines)

    def write(self, folder: Path) -> Path:
        """Write the HTML into ``folder`` (a temporary file renamed: never half a file)."""
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / self.file_name
        partial = folder / f".{self.file_name}.partial"
        partial.write_text(self.html(), encoding="utf-8")
        partial.replace(path)
        self.path = path
        return path


_NUMERIC = re.compile(r"[-+0-9.,:/ %x]*")


def _cell(value: str) -> str:
    """A table cell: numbers and times right-aligned, words left-aligned and wrapped."""
    kind = "num" if _NUMERIC.fullmatch(value) else "txt"
    return f"<td class='{kind}'>{html.escape(value)}</td>"


def _figure_title(figure: go.Figure) -> str:
    title = figure.layout.title.text if figure.layout.title else None
    return str(title or "figure")


_PLOT_CONFIG = {"displaylogo": False, "responsive": True, "scrollZoom": False}


def _figure_html(figure: go.Figure) -> str:
    return (
        "<div class='figure'>"
        + figure.to_html(
            full_html=False,
            include_plotlyjs=False,
            include_mathjax=False,
            config=_PLOT_CONFIG,
            default_width="100%",
            default_height=f"{int(figure.layout.height or 450)}px",
        )
        + "</div>"
    )


@cache
def _plotly_js() -> str:
    from plotly.offline import get_plotlyjs

    return get_plotlyjs().replace("</script", "<\\/script")


def tables_of(sections: Sequence[Section]) -> list[Table]:
    return [t for s in sections for t in s.tables]


_CSS = """
body { font-family: system-ui, -apple-system, 'Segoe UI', Roboto, Arial, sans-serif;
  color: #1b1b1b; background: #fafafa; margin: 0; }
main { max-width: 1500px; margin: 0 auto; padding: 16px 28px 60px; background: #fff; }
h1 { font-size: 26px; margin: 8px 0 6px; }
h2 { font-size: 21px; border-bottom: 2px solid #1f4e9c; padding-bottom: 4px; margin-top: 36px; }
h3 { font-size: 17px; margin-top: 26px; color: #1f4e9c; }
h4 { font-size: 14px; margin: 14px 0 4px; }
ul.about { color: #444; margin: 4px 0 12px; padding-left: 18px; }
nav ul { columns: 2; font-size: 14px; }
p { margin: 6px 0; font-size: 15px; line-height: 1.4; }
p.ok { color: #1b6e1b; }
p.warn { background: #fff4d6; border-left: 4px solid #e69500; padding: 4px 8px; }
p.fail { background: #fde4e4; border-left: 4px solid #d62728; padding: 4px 8px;
  font-weight: 600; }
p.note { color: #555; font-size: 13px; }
div.figure { margin: 10px 0 18px; border: 1px solid #e4e4e4; }
div.table { overflow-x: auto; max-height: 520px; overflow-y: auto; }
table { border-collapse: collapse; font-size: 13px; margin: 4px 0 8px; }
th, td { border: 1px solid #d8d8d8; padding: 3px 8px; }
th { background: #eef2f8; position: sticky; top: 0; text-align: center; }
td.num { text-align: right; white-space: nowrap; }
td.txt { text-align: left; max-width: 640px; }
"""
