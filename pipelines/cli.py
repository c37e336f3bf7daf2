"""The ``ropeload`` console script (contract section 6).

Every command parses its arguments here and calls the same plain function that the
Prefect flow of that command wraps (``pipelines/flows.py``), so the CLI and the flows
share one implementation. Exit status: 0 on success (also when rows were quarantined),
1 with a one-line reason on stderr when an input is refused or a run fails, 2 for a
usage error.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

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
    from pipelines.query import format_result, run_query
    from warehouse.store import DataRoot

    frame = run_query(args.sql, data=DataRoot.resolve(args.data))
    sys.stdout.write(format_result(frame, args.format))
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from pipelines.demo import run_demo
    from warehouse.store import DataRoot

    summary = run_demo(data=DataRoot.resolve(args.data), seed=args.seed, hours=args.hours)
    sys.stdout.write(summary)
    return 0


def _cmd_ingest(args: argparse.Namespace) -> int:
    from pipelines.ingest import ingest_paths
    from warehouse.store import DataRoot

    report = ingest_paths(args.paths, data=DataRoot.resolve(args.data))
    sys.stdout.write(f"{report}\n")
    return 0


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

    query = commands.add_parser("query", help="SQL on the warehouse, read-only")
    _data_option(query)
    query.add_argument("sql", help='e.g. "select * from position_summary"')
    query.add_argument("--format", choices=["table", "csv", "json"], default="table")
    query.set_defaults(handler=_cmd_query)
    return parser


def _known_errors() -> tuple[type[BaseException], ...]:
    import duckdb

    from schemas.hoist import HoistDescriptionError

    return (RopeloadError, HoistDescriptionError, FileNotFoundError, duckdb.Error, ValueError)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ropeload`` script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except _known_errors() as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        sys.stderr.write(f"ropeload {args.command}: {message}\n")
        return 1


if __name__ == "__main__":
    sys.exit(main())
