"""The command handlers of the ``ropeload`` console script (contract section 6).

Each ``cmd_<command>`` takes the parsed arguments (:func:`pipelines.cli_parser.build_parser`),
calls the same plain function that the Prefect flow of that command wraps
(``pipelines/flows.py``), prints the result on stdout and returns the exit status;
:class:`RopeloadError` is a refused input or failed run, which
:func:`pipelines.cli.main` prints as one line. Heavy modules are imported inside the
handlers, so building the parser stays cheap.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys

__all__ = [
    "RopeloadError",
    "cmd_backfill",
    "cmd_calibrate",
    "cmd_demo",
    "cmd_discover",
    "cmd_ingest",
    "cmd_nightly",
    "cmd_paper",
    "cmd_query",
    "cmd_run",
]


class RopeloadError(Exception):
    """A refused input or failed run; its message is the one line printed on stderr."""


def cmd_query(args: argparse.Namespace) -> int:
    from pipelines.query import QueryRefused, format_result, run_query
    from warehouse.store import DataRoot

    try:
        frame = run_query(args.sql, data=DataRoot.resolve(args.data))
    except QueryRefused as exc:
        raise RopeloadError(str(exc)) from exc
    sys.stdout.write(format_result(frame, args.format))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from pipelines.demo import run_demo
    from warehouse.store import DataRoot

    summary = run_demo(data=DataRoot.resolve(args.data), seed=args.seed, hours=args.hours)
    sys.stdout.write(summary)
    return 0


def cmd_ingest(args: argparse.Namespace) -> int:
    """The report on stdout; one ``ropeload ingest: <file>: <reason>`` line per refused
    file on stderr and exit 1 if any was refused (the other files landed)."""
    from pipelines.ingest import FilesRefused, ingest_paths
    from pipelines.ingest.field_checks import hoist_lookup_from_files
    from warehouse.store import DataRoot

    hoists = [str(p.absolute()) for p in args.hoist or []]
    lookup = hoist_lookup_from_files(hoists)  # an invalid description stops here
    if args.prefect:
        from pipelines.flows import ingest_flow

        try:
            report = ingest_flow(
                paths=[str(p) for p in args.paths],
                data=args.data,
                hoists=hoists,
                complete=args.complete,
            )
        except FilesRefused as exc:
            report = exc.report
    else:
        report = ingest_paths(
            args.paths,
            data=DataRoot.resolve(args.data),
            hoist_lookup=lookup,
            complete=args.complete,
        )
    sys.stdout.write(f"{report}\n")
    sys.stdout.flush()
    for line in report.refusal_lines():
        sys.stderr.write(f"ropeload ingest: {line}\n")
    return 0 if report.ok else 1


def cmd_calibrate(args: argparse.Namespace) -> int:
    from pipelines.calibrate import calibrate_rig
    from pipelines.calibrate_report import format_calibration, table1_report
    from warehouse.store import DataRoot

    if args.table1 is not None:
        if args.recordings or args.rig or args.parameter_set:
            sys.stderr.write(
                "ropeload calibrate: --table1 takes no --rig, --parameter-set or MCAP\n"
            )
            return 2
        import polars as pl

        try:
            report = table1_report(pl.read_csv(args.table1))
        except (ValueError, pl.exceptions.PolarsError) as exc:  # not Table 1: name the file
            raise ValueError(f"{args.table1}: {exc}") from None
        sys.stdout.write(report)
        return 0
    result = calibrate_rig(
        data=DataRoot.resolve(args.data),
        rig_id=args.rig,
        recordings=args.recordings,
        parameter_set=args.parameter_set,
    )
    sys.stdout.write(format_calibration(result))
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from warehouse.store import DataRoot

    checks, error = "", None
    if args.prefect:
        from pipelines.flows import run_flow
        from pipelines.reports import run_report_path

        result = run_flow(
            hoist=str(args.hoist.absolute()),
            data=args.data,
            start=args.start,
            end=args.end,
            payload_kg=args.payload_kg,
            sanity=not args.no_sanity,
            block_minutes=args.block_minutes,
            band_member_step_s=args.band_member_step,
            sanity_trips=args.sanity_trips,
        )
        report = run_report_path(DataRoot.resolve(args.data), result)
    else:
        from pipelines.run_period import run_checked
        from transforms.compensation_record import CompensationSettings

        checked = run_checked(
            hoist_path=args.hoist,
            data=DataRoot.resolve(args.data),
            start=args.start,
            end=args.end,
            payload_kg=args.payload_kg,
            sanity=not args.no_sanity,
            block=dt.timedelta(minutes=args.block_minutes),
            settings=CompensationSettings(band_member_step_s=args.band_member_step),
            sanity_trips=args.sanity_trips,
        )
        result, report, error = checked.result, checked.report, checked.sanity_error
        checks = "; " + checked.sanity_words
    sys.stdout.write(
        f"run {result.run_id}: {result.site}/{result.hoist} "
        f"{result.period_start_utc:%Y-%m-%d %H:%M:%S} .. {result.period_end_utc:%Y-%m-%d %H:%M:%S}"
        f" UTC, {result.samples} samples, {result.trip_summary.height} trips, "
        f"{result.position_summary.height} position visits, {result.alarms.height} alarms"
        f"{checks}\nreport: {report or 'not written (its run_steps row says why)'}\n"
    )
    if error is not None:  # the run is landed and reported; the check's failure fails it
        raise error
    return 0


def _fleet(args: argparse.Namespace, run_plain, run_flow) -> int:
    """Shared tail of backfill / nightly: plain functions or the flow; summary; status."""
    from pipelines.hoists import load_hoists
    from pipelines.progress import StderrProgress
    from warehouse.store import DataRoot

    data = DataRoot.resolve(args.data)
    if args.memory_budget_gb is not None:
        from pipelines.executors import workers_within_budget

        fit = workers_within_budget(args.workers, args.memory_budget_gb * 1e9)
        if fit < args.workers:
            sys.stderr.write(
                f"ropeload {args.command}: --workers {args.workers} -> {fit}, to stay within "
                f"--memory-budget-gb {args.memory_budget_gb:g}\n"
            )
            args.workers = fit
    if args.prefect or args.dask:
        from pipelines.flows import PartitionsFailed

        try:
            report = run_flow(data.path, not args.no_progress)
        except PartitionsFailed as exc:
            report = exc.report
    else:
        bar = None if args.no_progress else StderrProgress(0)
        if args.command == "nightly":  # a broken description holds up no other hoist
            unreadable: list[str] = []
            sources = load_hoists(
                args.hoists, data=data, incoming=args.incoming, unreadable=unreadable
            )
            report = run_plain(sources, data, bar, unreadable)
        else:
            sources = load_hoists(args.hoists, data=data, incoming=args.incoming)
            report = run_plain(sources, data, bar)
    sys.stdout.write(str(report))
    if not report.ok:
        raise RopeloadError(failure_line(report))
    return 0


def failure_line(report) -> str:
    """Why a backfill's or night's ``report`` is not ok, in one line: its failed
    partitions, else its refused files, the first one named with its reason."""
    failed = getattr(report, "runs", report).failed
    if failed:
        return f"{len(failed)} partition(s) failed (reasons above; also in the runs table)"
    errors = list(getattr(report, "hoist_errors", []))
    if errors:
        more = f" (and {len(errors) - 1} more, above)" if len(errors) > 1 else ""
        return f"{len(errors)} hoist(s) not run: {errors[0]}{more}"
    refused = list(getattr(report, "refused", []))
    if not refused:
        return "some files were refused (see above)"
    more = f" (and {len(refused) - 1} more, above)" if len(refused) > 1 else ""
    return f"some files were refused: {refused[0]}{more}"


def cmd_backfill(args: argparse.Namespace) -> int:
    def run_plain(sources, data, bar):
        from pipelines.backfill import backfill

        return backfill(
            sources,
            data=data,
            start=args.start,
            end=args.end,
            max_workers=args.workers,
            force=args.force,
            sanity=args.sanity,
            band_member_step_s=args.band_member_step,
            progress=bar,
            on_plan=None if bar is None else lambda plan: bar.resize(plan.total),
        )

    def run_flow(data, show_progress):
        from pipelines.flows import run_backfill_flow

        return run_backfill_flow(
            args.hoists,
            start=args.start,
            end=args.end,
            data=data,
            incoming=args.incoming,
            max_workers=args.workers,
            dask=args.dask,
            force=args.force,
            sanity=args.sanity,
            band_member_step_s=args.band_member_step,
            show_progress=show_progress,
        )

    return _fleet(args, run_plain, run_flow)


def cmd_nightly(args: argparse.Namespace) -> int:
    if len(args.hoists) != 1 and (args.prefect or args.dask):
        raise RopeloadError("--prefect / --dask take a single --hoists folder")

    def run_plain(sources, data, bar, unreadable):
        from pipelines.nightly import nightly

        return nightly(
            sources,
            unreadable=unreadable,
            data=data,
            max_workers=args.workers,
            lookback_days=args.lookback_days,
            sanity=not args.no_sanity,
            progress=bar,
            on_plan=None if bar is None else lambda partitions: bar.resize(len(partitions)),
        )

    def run_flow(data, show_progress):
        from pipelines.flows import run_nightly_flow

        return run_nightly_flow(
            args.hoists[0],
            data=data,
            incoming=args.incoming,
            lookback_days=args.lookback_days,
            max_workers=args.workers,
            dask=args.dask,
            sanity=not args.no_sanity,
            show_progress=show_progress,
        )

    return _fleet(args, run_plain, run_flow)


def cmd_discover(args: argparse.Namespace) -> int:
    import json

    from pipelines.discover import discover_period
    from warehouse.store import DataRoot

    try:
        out = discover_period(
            hoist_path=args.hoist,
            data=DataRoot.resolve(args.data),
            start=args.start,
            end=args.end,
            json_path=args.json,
        )
    except LookupError as exc:
        raise RopeloadError(str(exc)) from exc
    report = out.report
    summary = {k: report[k] for k in ("effect", "effects", "gap_before_pa", "gap_after_pa")}
    sys.stdout.write(json.dumps(summary) + "\n")
    return 0


def cmd_paper(args: argparse.Namespace) -> int:
    """Each section's table on stdout as soon as it is done; figures and rows in
    ``--out`` (default ``<data>/reports/paper``)."""
    from pipelines.paper import run_paper
    from warehouse.store import DataRoot

    out = args.out
    if out is None:
        out = DataRoot.resolve(args.data).under("reports", "paper")

    def emit(text: str) -> None:
        sys.stdout.write(text + "\n")
        sys.stdout.flush()

    run_paper([args.section], out, emit=emit)
    return 0
