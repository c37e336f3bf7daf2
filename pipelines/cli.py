"""The ``ropeload`` console script (contract section 6).

Every command parses its arguments here and calls the same plain function that the
Prefect flow of that command wraps (``pipelines/flows.py``), so the CLI and the flows
share one implementation. Exit status: 0 on success (also when rows were quarantined),
1 with a one-line reason on stderr when an input is refused or a run fails, 2 for a
usage error.
"""

from __future__ import annotations

import argparse
import datetime as dt
import errno
import os
import signal
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from pipelines.log import add_log_level_option, configure_logging

__all__ = ["RopeloadError", "build_parser", "main"]


class RopeloadError(Exception):
    """A refused input or failed run; its message is the one line printed on stderr."""


def _data_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--data",
        metavar="DIR",
        default=None,
        help="data root with the Parquet lake and warehouse.duckdb "
        "(default: $ROPELOAD_DATA, else ./ropeload-data)",
    )


def _hoist_option(parser: argparse.ArgumentParser, *, required: bool) -> None:
    parser.add_argument(
        "--hoist",
        metavar="FILE",
        type=Path,
        required=required,
        help="hoist description TOML (layout: schemas/hoists/README.md)",
    )


def _cmd_query(args: argparse.Namespace) -> int:
    from pipelines.query import QueryRefused, format_result, run_query
    from warehouse.store import DataRoot

    try:
        frame = run_query(args.sql, data=DataRoot.resolve(args.data))
    except QueryRefused as exc:
        raise RopeloadError(str(exc)) from exc
    sys.stdout.write(format_result(frame, args.format))
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from pipelines.demo import run_demo
    from warehouse.store import DataRoot

    summary = run_demo(data=DataRoot.resolve(args.data), seed=args.seed, hours=args.hours)
    sys.stdout.write(summary)
    return 0


def _cmd_ingest(args: argparse.Namespace) -> int:
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
            report = ingest_flow(paths=[str(p) for p in args.paths], data=args.data, hoists=hoists)
        except FilesRefused as exc:
            report = exc.report
    else:
        report = ingest_paths(args.paths, data=DataRoot.resolve(args.data), hoist_lookup=lookup)
    sys.stdout.write(f"{report}\n")
    sys.stdout.flush()
    for line in report.refusal_lines():
        sys.stderr.write(f"ropeload ingest: {line}\n")
    return 0 if report.ok else 1


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from pipelines.calibrate import calibrate_rig, format_calibration, table1_report
    from warehouse.store import DataRoot

    if args.table1 is not None:
        if args.recordings or args.rig or args.parameter_set:
            sys.stderr.write(
                "ropeload calibrate: --table1 takes no --rig, --parameter-set or MCAP\n"
            )
            return 2
        import polars as pl

        sys.stdout.write(table1_report(pl.read_csv(args.table1)))
        return 0
    result = calibrate_rig(
        data=DataRoot.resolve(args.data),
        rig_id=args.rig,
        recordings=args.recordings,
        parameter_set=args.parameter_set,
    )
    sys.stdout.write(format_calibration(result))
    return 0


def _prefect_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--prefect",
        action="store_true",
        help="run as the Prefect flow of the same name (a flow run, task runs, artifacts); "
        "without PREFECT_API_URL a temporary local server is started (~15 s)",
    )


def _fleet_options(parser: argparse.ArgumentParser) -> None:
    """Options of the many-hoist commands (backfill, nightly)."""
    _data_option(parser)
    parser.add_argument(
        "--hoists",
        metavar="DIR",
        type=Path,
        action="append",
        required=True,
        help="folder of hoist descriptions (*.toml), or one file; repeatable",
    )
    parser.add_argument(
        "--incoming",
        metavar="DIR",
        type=Path,
        default=None,
        help="raw logs as <incoming>/<site>/<hoist>/... (default <data>/incoming)",
    )
    parser.add_argument(
        "--workers", type=int, default=2, help="hoist-days processed at a time (default 2)"
    )
    parser.add_argument(
        "--memory-budget-gb",
        type=_positive_gb,
        default=None,
        metavar="G",
        help="use fewer --workers if their estimated memory (about 0.9 GB + 0.4 GB a "
        "worker at 100 Hz) exceeds G GB",
    )
    parser.add_argument(
        "--dask",
        metavar="ADDRESS",
        default=None,
        help="run the flow on a Dask cluster: a scheduler address or 'local' "
        "(a LocalCluster of --workers processes); implies --prefect",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    _prefect_option(parser)


def _parse_time(text: str):
    import datetime as dt

    value = dt.datetime.fromisoformat(text)
    return value.replace(tzinfo=dt.UTC) if value.tzinfo is None else value


def _parse_day(text: str):
    import datetime as dt

    return dt.date.fromisoformat(text)


def _positive_gb(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a positive number of GB, got {text}")
    return value


def _positive_minutes(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a positive number of minutes, got {text}")
    return value


def _cmd_run(args: argparse.Namespace) -> int:
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
        )
        report = run_report_path(DataRoot.resolve(args.data), result)
    else:
        from pipelines.run_period import run_checked

        checked = run_checked(
            hoist_path=args.hoist,
            data=DataRoot.resolve(args.data),
            start=args.start,
            end=args.end,
            payload_kg=args.payload_kg,
            sanity=not args.no_sanity,
            block=dt.timedelta(minutes=args.block_minutes),
        )
        result, report, error = checked.result, checked.report, checked.sanity_error
        checks = "; " + checked.sanity_words
    sys.stdout.write(
        f"run {result.run_id}: {result.site}/{result.hoist} "
        f"{result.period_start_utc:%Y-%m-%d %H:%M:%S} .. {result.period_end_utc:%Y-%m-%d %H:%M:%S}"
        f" UTC, {result.samples} samples, {result.trip_summary.height} trips, "
        f"{result.position_summary.height} position visits, {result.alarms.height} alarms"
        f"{checks}\nreport: {report}\n"
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
        sources = load_hoists(args.hoists, data=data, incoming=args.incoming)
        report = run_plain(sources, data, None if args.no_progress else StderrProgress(0))
    sys.stdout.write(str(report))
    if not report.ok:
        failed = getattr(report, "runs", report).failed
        raise RopeloadError(
            f"{len(failed)} partition(s) failed (reasons above; also in the runs table)"
            if failed
            else "some files were refused (see above)"
        )
    return 0


def _cmd_backfill(args: argparse.Namespace) -> int:
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
            show_progress=show_progress,
        )

    return _fleet(args, run_plain, run_flow)


def _cmd_nightly(args: argparse.Namespace) -> int:
    if len(args.hoists) != 1 and (args.prefect or args.dask):
        raise RopeloadError("--prefect / --dask take a single --hoists folder")

    def run_plain(sources, data, bar):
        from pipelines.nightly import nightly

        return nightly(
            sources,
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


def _add_flow_commands(commands) -> None:
    """``run``, ``backfill`` and ``nightly`` (issue 7); ``--prefect`` runs their flows."""
    from pipelines.night_options import add_night_options

    run = commands.add_parser(
        "run", help="compensate + reconcile + alarm a period of one hoist, and land it"
    )
    _data_option(run)
    _hoist_option(run, required=True)
    run.add_argument("--from", dest="start", type=_parse_time, metavar="T", help="UTC if no offset")
    run.add_argument("--to", dest="end", type=_parse_time, metavar="T", help="exclusive")
    run.add_argument("--payload-kg", type=float, default=None, help="known payload at standstill")
    run.add_argument("--no-sanity", action="store_true", help="skip the simulation sanity check")
    run.add_argument(
        "--block-minutes",
        type=_positive_minutes,
        default=60.0,
        metavar="M",
        help="samples are processed M minutes at a time: memory grows with M, not with "
        "the period (default 60; results do not depend on it)",
    )
    _prefect_option(run)
    run.set_defaults(handler=_cmd_run)

    backfill = commands.add_parser(
        "backfill", help="every hoist-day of a date range: resumable, bounded concurrency"
    )
    _fleet_options(backfill)
    backfill.add_argument(
        "--from", dest="start", type=_parse_day, required=True, metavar="DAY", help="UTC day"
    )
    backfill.add_argument(
        "--to", dest="end", type=_parse_day, required=True, metavar="DAY", help="UTC day, included"
    )
    backfill.add_argument("--force", action="store_true", help="re-run days the ledger marks done")
    backfill.add_argument(
        "--sanity", action="store_true", help="also run the simulation sanity check per day"
    )
    backfill.set_defaults(handler=_cmd_backfill)

    nightly = commands.add_parser(
        "nightly", help="every hoist's new raw files since its watermark, processed and landed"
    )
    _fleet_options(nightly)
    add_night_options(nightly)  # shared with python -m pipelines.deploy serve|pool
    nightly.set_defaults(handler=_cmd_nightly)


def _cmd_discover(args: argparse.Namespace) -> int:
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


#: ``ropeload paper`` sections (the keys of :data:`pipelines.paper.SECTIONS`, named here
#: so that building the parser imports nothing heavy) and ``all``.
PAPER_SECTIONS = ("table1", "table2", "eq9-10", "section3.1", "all")


def _cmd_paper(args: argparse.Namespace) -> int:
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


def _add_paper_command(commands) -> None:
    paper = commands.add_parser(
        "paper",
        help="the paper's tables, eq 9/10 and section 3.1 beside ropeload's numbers, with figures",
    )
    _data_option(paper)
    paper.add_argument(
        "section",
        nargs="?",
        default="all",
        choices=PAPER_SECTIONS,
        help="table1: OLS vs eq 17; table2: the field test; eq9-10: section 2.2 by formula "
        "and simulation; section3.1: the rig's pressure loss (default: all)",
    )
    paper.add_argument(
        "--out",
        metavar="DIR",
        type=Path,
        default=None,
        help="folder for the figures (PNG) and rows (CSV) (default: <data>/reports/paper)",
    )
    paper.set_defaults(handler=_cmd_paper)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ropeload",
        description="Rope tensions and hoist loads from hydraulic rope-attachment pressures.",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    demo = commands.add_parser(
        "demo", help="the whole job on built-in synthetic data, nothing to configure"
    )
    _data_option(demo)
    demo.add_argument("--seed", type=int, default=7, help="random seed of the synthetic day")
    demo.add_argument("--hours", type=float, default=1.0, help="hours of logs to generate")
    demo.set_defaults(handler=_cmd_demo)

    ingest = commands.add_parser(
        "ingest", help="land raw field logs (CSV, TDMS) and rig recordings (MCAP)"
    )
    _data_option(ingest)
    ingest.add_argument("paths", nargs="+", type=Path, metavar="PATH", help="files or folders")
    ingest.add_argument(
        "--hoist",
        metavar="FILE",
        type=Path,
        action="append",
        help="hoist description TOML of the logs' hoist (repeatable, one per hoist): depth "
        "outside its shaft is quarantined; without one only depth above the pithead is",
    )
    _prefect_option(ingest)
    ingest.set_defaults(handler=_cmd_ingest)

    calibrate = commands.add_parser(
        "calibrate", help="friction-rig recordings (MCAP) -> seal-friction parameter set"
    )
    _data_option(calibrate)
    calibrate.add_argument(
        "--rig", metavar="RIG_ID", help="rig to calibrate (default: the only one)"
    )
    calibrate.add_argument("--parameter-set", metavar="NAME", help="name of the parameter set")
    calibrate.add_argument(
        "--table1", metavar="FILE", type=Path, help="report OLS lines through paper Table 1 (CSV)"
    )
    calibrate.add_argument(
        "recordings", nargs="*", type=Path, metavar="MCAP", help="recordings to ingest and use"
    )
    calibrate.set_defaults(handler=_cmd_calibrate)

    _add_flow_commands(commands)

    discover = commands.add_parser(
        "discover", help="name the effect missing from a hoist's model (contract section 5)"
    )
    _data_option(discover)
    _hoist_option(discover, required=True)
    discover.add_argument(
        "--from", dest="start", type=_parse_time, metavar="T", help="UTC if no offset"
    )
    discover.add_argument("--to", dest="end", type=_parse_time, metavar="T", help="exclusive")
    discover.add_argument(
        "--json", type=Path, required=True, metavar="FILE", help="report to write"
    )
    discover.set_defaults(handler=_cmd_discover)

    query = commands.add_parser("query", help="SQL on the warehouse, read-only")
    _data_option(query)
    query.add_argument("sql", help='e.g. "select * from position_summary"')
    query.add_argument("--format", choices=["table", "csv", "json"], default="table")
    query.set_defaults(handler=_cmd_query)
    _add_paper_command(commands)
    for subcommand in commands.choices.values():
        add_log_level_option(subcommand)
    return parser


def _known_errors() -> tuple[type[BaseException], ...]:
    """Errors the user can cause: their message is the one line (no traceback).

    Only evaluated when an exception reaches :func:`main`. Error classes of heavy
    modules are taken only if the module is loaded (if it is not, it raised nothing).
    """
    import duckdb

    from schemas.hoist import HoistDescriptionError
    from warehouse.lock import LockTimeoutError

    known: list[type[BaseException]] = [
        RopeloadError,
        HoistDescriptionError,
        FileNotFoundError,
        duckdb.Error,
        ValueError,
        LockTimeoutError,
    ]
    run_period = sys.modules.get("pipelines.run_period")
    if run_period is not None:
        known.append(run_period.NoSamplesError)
    return tuple(known)


#: OSError numbers the user causes (permissions, full disk, a file where a folder
#: belongs, ulimit -n): one line naming the file. Others are bugs: traceback.
_USER_ERRNOS = frozenset(
    getattr(errno, name)
    for name in (
        "EACCES", "EPERM", "EROFS", "ENOSPC", "EDQUOT", "ENOTDIR", "EISDIR", "EEXIST",
        "ENAMETOOLONG", "ELOOP", "EMFILE", "ENFILE", "EFBIG",
    )
    if hasattr(errno, name)
)  # fmt: skip


def _os_error_line(exc: OSError) -> str:
    """``Permission denied: /data/.warehouse.lock`` (with the second path of a rename)."""
    reason = exc.strerror or type(exc).__name__
    paths = [str(p) for p in (exc.filename, exc.filename2) if p is not None]
    return f"{reason}: {' -> '.join(paths)}" if paths else reason


def _data_root_problem(args: argparse.Namespace) -> str | None:
    """Why the command's data root cannot be used, or None.

    A data root that exists must be a folder; a command that writes (all but ``query``,
    ``calibrate --table1`` and ``paper --out``) needs it writable, or creatable: its
    nearest existing ancestor a writable folder. (As root, permission bits do not stop writes, and
    ``os.access`` says so too; a read-only file system still does.)
    """
    if not hasattr(args, "data") or (args.command == "calibrate" and args.table1):
        return None
    if args.command == "paper" and args.out is not None:  # the data root is not used
        return None
    from warehouse.store import DATA_ENV, DataRoot

    path = DataRoot.resolve(args.data).path
    origin = "--data" if args.data is not None else f"${DATA_ENV}"
    if args.data is None and not os.environ.get(DATA_ENV):
        origin = "the default"
    writes = args.command != "query"
    existing = path
    while not os.path.lexists(existing) and existing != existing.parent:
        existing = existing.parent
    what = f"data root {path} ({origin})"
    if existing == path:
        if not path.is_dir():
            return f"{what} is {'a file, ' if path.is_file() else ''}not a folder"
        if writes and not os.access(path, os.W_OK | os.X_OK):
            return f"{what} is not writable ({_why_not_writable(path)})"
        return None
    if not existing.is_dir():
        return f"{what} cannot be created: {existing} is a file, not a folder"
    if writes and not os.access(existing, os.W_OK | os.X_OK):
        why = _why_not_writable(existing)
        return f"{what} cannot be created: {existing} is not writable ({why})"
    return None


def _why_not_writable(path: Path) -> str:
    try:
        if os.statvfs(path).f_flag & os.ST_RDONLY:
            return "read-only file system"
    except OSError:
        pass
    return "permission denied"


def _supervised(args: argparse.Namespace) -> bool:
    """Whether the command starts servers or worker processes (then it is supervised)."""
    return bool(getattr(args, "prefect", False) or getattr(args, "dask", None))


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ropeload`` script; returns the exit status.

    Everything the user can cause ends as one line ``ropeload <command>: <reason>`` on
    stderr with status 1 (2 for usage): refused input, a data root that is a file or
    not writable, the warehouse lock timing out, memory exhaustion; SIGTERM/SIGHUP and
    Ctrl-C end the command cleanly (status 143/129/130). An unexpected internal error
    still prints its traceback: that is a bug report.

    As the console script (``argv`` None), a command under a memory limit, or one that
    starts servers and workers (``--prefect``, ``--dask``), runs in a child of this
    process (:func:`pipelines.supervise.run_supervised`), which reports the child's
    death by memory exhaustion and ends whatever it left running.
    """
    from pipelines import exits
    from warehouse.lock import INVOCATION_ENV, lock_timeout_s

    parser = build_parser()
    args = parser.parse_args(argv)
    configure_logging(getattr(args, "log_level", None))  # stderr; stdout: the result
    command: str = args.command
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        lock_timeout_s()
    except ValueError as exc:
        sys.stderr.write(f"ropeload {command}: {exc}\n")
        return 2
    problem = _data_root_problem(args)
    if problem is not None:
        sys.stderr.write(f"ropeload {command}: {problem}\n")
        return 1
    os.environ.setdefault(INVOCATION_ENV, f"{os.getpid()}-{time.time_ns()}")
    limit = exits.memory_limit()
    if argv is None and (limit is not None or _supervised(args)):
        from pipelines import supervise

        if supervise.can_supervise():
            status = supervise.run_supervised(command, limit)
            if status is not None:
                return status  # the supervisor; the child goes on below
    message: str
    try:
        with exits.terminate_on_signals():
            return handler(args)
    except _known_errors() as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", signal.SIGINT)
        sys.stderr.write(f"ropeload {command}: interrupted ({signal.Signals(signum).name})\n")
        return 128 + signum
    except (MemoryError, ImportError, OSError, SystemError, RuntimeError) as exc:
        if exits.memory_exhausted(exc, limit):
            message = exits.out_of_memory(command, limit)
        elif isinstance(exc, OSError) and exc.errno in _USER_ERRNOS:
            message = _os_error_line(exc)
        else:
            raise
    sys.stderr.write(f"ropeload {command}: {message}\n")
    return 1


if __name__ == "__main__":
    sys.exit(main())
