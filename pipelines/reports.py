"""Run reports: markdown with plots and tables, for a night or a backfill.

:func:`build_report` reads what the partitions landed (rope tensions from the lake,
``position_summary`` and ``alarms`` from the warehouse) and returns a :class:`Report`:

* a markdown document: summary, failed partitions with reasons, per hoist-day plots of
  the load before / after compensation and the four rope tensions, reconciliation per
  hoist position (error against the expected load before and after compensation) and
  the alarms;
* tables (lists of row dicts) for Prefect table artifacts;
* the PNG files (matplotlib, Agg backend, headless), saved under ``out_dir`` and
  embedded in the markdown as data URIs so the Prefect UI shows them without a file
  server.

Plain functions, no Prefect: :mod:`pipelines.flows` publishes the result as artifacts
(``create_markdown_artifact`` / ``create_table_artifact``).
"""

from __future__ import annotations

import base64
import datetime as dt
import io
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import polars as pl

from pipelines.backfill import PartitionOutcome
from pipelines.lake import scan_lake
from schemas.names import join_inside
from warehouse.store import DataRoot, open_reader

__all__ = ["Report", "alarms_of", "build_report", "reconciliation_by_position"]

_MAX_POINTS = 4000
_MAX_TABLE_ROWS = 200


@dataclass
class Report:
    """A markdown report, its tables and the figure files."""

    title: str
    markdown: str
    tables: dict[str, list[dict[str, object]]] = field(default_factory=dict)
    figures: list[Path] = field(default_factory=list)


def _select_runs(data: DataRoot, table: str, run_ids: Sequence[str], order: str) -> pl.DataFrame:
    if not run_ids or not data.warehouse.exists():
        return pl.DataFrame()
    con = open_reader(data)
    try:
        return con.sql(
            f"SELECT * FROM {table} WHERE list_contains($ids, run_id) ORDER BY {order}",
            params={"ids": list(run_ids)},
        ).pl()
    finally:
        con.close()


def reconciliation_by_position(data: DataRoot, run_ids: Sequence[str]) -> pl.DataFrame:
    """Per hoist and position: visits and mean / worst |error| before and after [%]."""
    summary = _select_runs(data, "position_summary", run_ids, "site, hoist, time_start_utc")
    if summary.height == 0:
        return summary
    return (
        summary.group_by("site", "hoist", "position")
        .agg(
            pl.len().alias("visits"),
            (pl.col("error_before_fraction").abs().mean() * 100).alias("mean_err_before_pct"),
            (pl.col("error_after_fraction").abs().mean() * 100).alias("mean_err_after_pct"),
            (pl.col("error_before_fraction").abs().max() * 100).alias("max_err_before_pct"),
            (pl.col("error_after_fraction").abs().max() * 100).alias("max_err_after_pct"),
            pl.col("depth_m").mean().alias("depth_m"),
        )
        .sort("site", "hoist", "depth_m")
        .with_columns(pl.selectors.float().round(3))
    )


def alarms_of(data: DataRoot, run_ids: Sequence[str]) -> pl.DataFrame:
    """The alarms the runs landed, oldest first."""
    return _select_runs(data, "alarms", run_ids, "start_utc")


def _png(figure: plt.Figure, path: Path) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=72, bbox_inches="tight")
    plt.close(figure)
    path.write_bytes(buffer.getvalue())
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _tension_figure(data: DataRoot, outcome: PartitionOutcome, path: Path) -> str | None:
    start = dt.datetime.combine(outcome.day, dt.time(0), tzinfo=dt.UTC)
    frame = scan_lake(
        data,
        "rope_tensions",
        site=outcome.site,
        hoist=outcome.hoist,
        start=start,
        end=start + dt.timedelta(days=1),
    ).select(
        "time_utc", "load_raw_n", "load_n", "tension1_n", "tension2_n", "tension3_n", "tension4_n"
    )
    rows = frame.select(pl.len()).collect().item()
    if rows == 0:
        return None
    frame = frame.gather_every(max(1, rows // _MAX_POINTS)).collect()
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(9, 5), sharex=True)
    time = frame["time_utc"].to_numpy()
    top.plot(time, frame["load_raw_n"].to_numpy() / 1e3, lw=0.7, label="before (p x A)")
    top.plot(time, frame["load_n"].to_numpy() / 1e3, lw=0.7, label="after compensation")
    top.set_ylabel("load [kN]")
    top.legend(loc="upper right", fontsize=8)
    top.set_title(f"{outcome.key}: conveyance load before / after compensation", fontsize=10)
    for rope in range(1, 5):
        bottom.plot(time, frame[f"tension{rope}_n"].to_numpy() / 1e3, lw=0.6, label=f"rope {rope}")
    bottom.set_ylabel("tension [kN]")
    bottom.set_xlabel("time [UTC]")
    bottom.legend(loc="upper right", fontsize=8, ncol=4)
    return _png(figure, path)


def _reconciliation_figure(by_position: pl.DataFrame, path: Path) -> str:
    labels = [f"{r['hoist']}\n{r['position']}" for r in by_position.iter_rows(named=True)]
    x = range(len(labels))
    figure, axis = plt.subplots(figsize=(max(5, 1.2 * len(labels)), 3.5))
    width = 0.4
    axis.bar([i - width / 2 for i in x], by_position["mean_err_before_pct"], width, label="before")
    axis.bar([i + width / 2 for i in x], by_position["mean_err_after_pct"], width, label="after")
    axis.set_xticks(list(x), labels, fontsize=8)
    axis.set_ylabel("mean |load error| [%]")
    axis.set_title("reconciliation per position: error against the expected load", fontsize=10)
    axis.legend(fontsize=8)
    return _png(figure, path)


def _alarm_figure(alarms: pl.DataFrame, path: Path) -> str:
    rules = sorted(alarms["rule"].unique().to_list())
    figure, axis = plt.subplots(figsize=(9, 0.6 * len(rules) + 1.5))
    for k, rule in enumerate(rules):
        part = alarms.filter(pl.col("rule") == rule)
        axis.scatter(part["start_utc"].to_numpy(), [k] * part.height, marker="|", s=200)
    axis.set_yticks(range(len(rules)), rules, fontsize=8)
    axis.set_xlabel("start [UTC]")
    axis.set_title(f"{alarms.height} alarms", fontsize=10)
    return _png(figure, path)


def _md_table(frame: pl.DataFrame, limit: int = 30) -> str:
    if frame.height == 0:
        return "_none_\n"
    shown = frame.head(limit)
    head = "| " + " | ".join(shown.columns) + " |"
    rule = "|" + "---|" * len(shown.columns)
    rows = [
        "| " + " | ".join("" if v is None else str(v).replace("|", "/") for v in row) + " |"
        for row in shown.iter_rows()
    ]
    more = (
        f"\n_{frame.height - limit} more rows in the table artifact_\n"
        if frame.height > limit
        else ""
    )
    return "\n".join([head, rule, *rows]) + "\n" + more


def _rows(frame: pl.DataFrame) -> list[dict[str, object]]:
    out = frame.head(_MAX_TABLE_ROWS).with_columns(
        pl.col(pl.Datetime).dt.strftime("%Y-%m-%d %H:%M:%S")
    )
    return out.to_dicts()


def build_report(
    data: DataRoot,
    outcomes: Sequence[PartitionOutcome],
    *,
    title: str,
    out_dir: str | Path | None = None,
    preamble: str = "",
    max_plotted_days: int = 4,
) -> Report:
    """Markdown, tables and figures for the partitions of a night or backfill.

    Tension plots are drawn for the latest ``max_plotted_days`` succeeded hoist-days;
    figures go to ``out_dir`` (default ``<data>/reports/<UTC timestamp>``).
    """
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    folder = Path(out_dir) if out_dir is not None else data.under("reports", stamp)
    ran = sorted((o for o in outcomes if o.status == "succeeded"), key=lambda o: o.key)
    run_ids = [o.run_id for o in ran if o.run_id]
    failed = sorted((o for o in outcomes if o.status == "failed"), key=lambda o: o.key)
    counts = {
        s: sum(o.status == s for o in outcomes) for s in ("succeeded", "skipped", "empty", "failed")
    }
    report = Report(title=title, markdown="")
    parts = [
        f"# {title}\n",
        preamble,
        f"{len(outcomes)} hoist-days: **{counts['succeeded']} run**, {counts['skipped']} already "
        f"done, {counts['empty']} without data, **{counts['failed']} failed**; "
        f"{sum(o.samples for o in ran)} samples.\n",
    ]
    partitions = pl.DataFrame(
        [o.row() for o in sorted(outcomes, key=lambda o: o.key)],
        schema={
            "partition": pl.String,
            "status": pl.String,
            "samples": pl.Int64,
            "files_ingested": pl.Int64,
            "attempts": pl.Int64,
            "seconds": pl.Float64,
            "run_id": pl.String,
            "message": pl.String,
        },
    )
    report.tables["partitions"] = _rows(partitions)
    if failed:
        parts.append("## Failed partitions\n")
        parts.append(_md_table(partitions.filter(pl.col("status") == "failed")))
    if ran:
        parts.append("## Tensions before / after compensation\n")
        for outcome in ran[-max_plotted_days:]:
            name = f"tensions_{outcome.site}_{outcome.hoist}_{outcome.day}.png"
            path = join_inside(folder, name, source="report")  # names from data: no escape
            encoded = _tension_figure(data, outcome, path)
            if encoded is not None:
                report.figures.append(path)
                parts.append(f"![{outcome.key}](data:image/png;base64,{encoded})\n")
    by_position = reconciliation_by_position(data, run_ids)
    if by_position.height:
        parts.append("## Reconciliation per position\n")
        path = folder / "reconciliation.png"
        encoded = _reconciliation_figure(by_position, path)
        parts.append(f"![reconciliation](data:image/png;base64,{encoded})\n")
        report.figures.append(path)
        parts.append(_md_table(by_position))
        report.tables["reconciliation"] = _rows(by_position)
    if ran:
        alarms = alarms_of(data, run_ids)
        parts.append(f"## Alarms ({alarms.height})\n")
        if alarms.height:
            path = folder / "alarms.png"
            parts.append(f"![alarms](data:image/png;base64,{_alarm_figure(alarms, path)})\n")
            report.figures.append(path)
        shown = (
            alarms.select(
                "site",
                "hoist",
                "rule",
                "rope",
                "start_utc",
                "end_utc",
                "peak_value",
                "threshold",
                "unit",
                "message",
            )
            if alarms.height
            else alarms
        )
        parts.append(_md_table(shown))
        report.tables["alarms"] = _rows(shown)
    if report.figures:
        parts.append(f"\n_Figures saved under `{folder}`._\n")
    report.markdown = "\n".join(p for p in parts if p)
    return report
