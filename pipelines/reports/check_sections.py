"""The sections of a hoist-period that report its checks.

The simulation sanity check (:func:`sanity_section`) and the discovery findings with
their residual trace (:func:`discovery_sections`); called by
:func:`pipelines.reports.sections.hoist_sections`.
"""

from __future__ import annotations

import json
import re

import polars as pl

from pipelines.reports import check_figures
from pipelines.reports.document import Section, Table
from pipelines.reports.period import HoistPeriod, num_text
from warehouse.store import DataRoot

__all__ = ["discovery_sections", "sanity_section"]


_LIMIT = re.compile(r"limit ([0-9.]+) x")


def sanity_section(period: HoistPeriod, checks: pl.DataFrame) -> Section:
    section = Section("Sanity check against the simulation", level=3)
    step = next((s for s in period.steps if s.name == "sanity check"), None)
    if step is not None and step.status != "done":
        section.say(step.sentence(), "fail" if step.status == "failed" else "info")
    if not checks.height:
        if step is None or step.status == "done":
            section.say("No trip was checked against the simulation in this period.")
        return section
    if "status" not in checks.columns:
        checks = checks.with_columns(
            pl.when(pl.col("passed"))
            .then(pl.lit("passed"))
            .otherwise(pl.lit("failed"))
            .alias("status")
        )
    checks = checks.with_columns(
        pl.col("status").fill_null(
            pl.when(pl.col("passed")).then(pl.lit("passed")).otherwise(pl.lit("failed"))
        )
    )
    failed = checks.filter(pl.col("status") == "failed")
    compared = checks.filter(pl.col("status") != "skipped")
    skipped = checks.height - compared.height
    section.say(
        f"{compared.height - failed.height} of {compared.height} trips passed: the RMS of "
        "measured minus simulated sensor pressure within the limit times the sensor noise"
        + (f"; {skipped} trip(s) could not be compared (reasons in the table)" if skipped else "")
        + ".",
        "warn" if failed.height else "ok",
    )
    factor = [float(m.group(1)) if (m := _LIMIT.search(msg or "")) else None
              for msg in checks["message"].to_list()]  # fmt: skip
    checks = checks.with_columns(
        pl.Series("factor", factor, dtype=pl.Float64),
        pl.format("trip {}", pl.col("trip_id")).alias("label"),
    ).with_columns((pl.col("factor") * pl.col("noise_pa")).alias("limit_pa"))
    section.figures.append(
        check_figures.sanity_figure(
            checks,
            title="Measured minus simulated sensor pressure, RMS per trip, against the pass "
            f"limit, {period.site}/{period.hoist}, {period.label}",
        )
    )
    rows = [
        [
            str(r["trip_id"]),
            "FAILED" if r["status"] == "failed" else str(r["status"]),
            num_text(r["rms_gap_pa"], 1e3),
            num_text(r["noise_pa"], 1e3),
            ""
            if not r["noise_pa"] or r["rms_gap_pa"] is None or r["rms_gap_pa"] != r["rms_gap_pa"]
            else f"{r['rms_gap_pa'] / r['noise_pa']:.2f}",
            r["message"] or "",
        ]
        for r in checks.iter_rows(named=True)
    ]
    section.tables.append(
        Table("", ["trip", "check", "RMS gap [kPa]", "noise [kPa]", "gap / noise", "what"],
              rows, key="sanity")
    )  # fmt: skip
    return section


def discovery_sections(data: DataRoot, period: HoistPeriod) -> list[Section]:
    from pipelines.reports.data import discovery_rows

    section = Section("Discovery: what the hoist's model misses", level=3)
    step = next((s for s in period.steps if s.name == "discovery"), None)
    rows = discovery_rows(
        data, site=period.site, hoist=period.hoist, start=period.start_utc, end=period.end_utc
    )
    if step is not None and (step.status != "skipped" or not rows.height):
        section.say(step.sentence(), "fail" if step.status == "failed" else "info")
    if not rows.height:
        if step is None:
            section.say("No discovery findings are landed for this period.")
        return [section]
    section.say(
        "Findings of the discovery runs over this period (each iteration adds the effect it "
        "names to the model and looks again):"
    )
    table_rows = []
    found: list[str] = []
    sections = [section]
    zone = period.zone
    for row in rows.iter_rows(named=True):
        obj = json.loads(row["report_json"])
        table_rows.append(
            [
                row["run_id"],
                str(row["iteration"]),
                row["effect"],
                "" if row["confidence"] is None else f"{row['confidence']:.2f}",
                num_text(row["gap_before_pa"], 1e3),
                num_text(row["gap_after_pa"], 1e3),
                num_text(obj.get("noise_pa"), 1e3),
                f"{zone.text(row['period_start_utc'], '%Y-%m-%d %H:%M')} .. "
                f"{zone.text(row['period_end_utc'], '%Y-%m-%d %H:%M')}",
            ]
        )
        effect = row["effect"]
        if effect not in ("none", "ambiguous"):
            found.append(effect)
        regions = obj.get("where") or []
        if regions:
            added = effect not in ("none", "ambiguous")
            what = f"before and after adding {effect}" if added else f"no further effect ({effect})"
            section.figures.append(
                check_figures.discovery_regions_figure(
                    regions,
                    noise_pa=obj.get("noise_pa"),
                    effect=effect if added else None,
                    title=f"Measured minus simulated pressure per regime, {period.hoist}, "
                    f"iteration {row['iteration']}: {what}",
                )
            )
    section.say(
        "Effects found: " + (", ".join(found) if found else "none (the model explains the data)")
        + "."
    )  # fmt: skip
    zone_words = zone.label(period.start_utc, period.end_utc)
    section.tables.insert(
        0,
        Table(
            "",
            ["discovery run", "iteration", "effect", "confidence", "gap before [kPa]",
             "gap after [kPa]", "noise [kPa]", f"period ({zone_words})"],
            table_rows,
            key="discovery",
        ),
    )  # fmt: skip
    trace = _residual_trace(data, period)
    if trace is not None:
        added = ", ".join(trace.get("effects") or found) or "nothing"
        section.figures.append(
            check_figures.discovery_trace_figure(
                trace,
                title=f"Measured minus simulated pressure, sensor {trace.get('sensor')}, trip "
                f"{trace.get('trip_id')} ({trace.get('direction')}), before and after adding "
                f"{added}",
            )
        )
    return sections


def _residual_trace(data: DataRoot, period: HoistPeriod) -> dict[str, object] | None:
    """The worst trip's residual from the discovery JSON of this period, if written."""
    path = period.discovery_json
    if path is None:
        day = period.start_utc.date()
        try:
            path = data.under("reports", "discovery", f"{period.site}_{period.hoist}_{day}.json")
        except ValueError:
            return None
    if not path.is_file():
        return None
    try:
        trace = json.loads(path.read_text()).get("residual_trace")
    except (OSError, ValueError):
        return None
    return trace if isinstance(trace, dict) and isinstance(trace.get("before"), dict) else None
