"""The argument parser of the ``ropeload`` console script (contract section 6).

:func:`build_parser` declares every command, its options and its handler (in
:mod:`pipelines.cli_commands`); it imports nothing heavy.
"""

from __future__ import annotations

import argparse
import datetime as dt
import math
from pathlib import Path
from typing import NoReturn

from pipelines.cli_commands import (
    cmd_backfill,
    cmd_calibrate,
    cmd_demo,
    cmd_discover,
    cmd_ingest,
    cmd_nightly,
    cmd_paper,
    cmd_query,
    cmd_run,
)
from pipelines.log import add_log_level_option

__all__ = ["PAPER_SECTIONS", "build_parser", "data_dir"]


def data_dir(text: str) -> str:
    """A data root: a usage error when empty (``--data "$UNSET"``), which would otherwise
    make the working directory the data root and land the lake and warehouse there."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "empty; name a folder (or leave --data out for $ROPELOAD_DATA, else ./ropeload-data)"
        )
    return text


def _data_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--data",
        metavar="DIR",
        type=data_dir,
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
        "--workers",
        type=_at_least_one,
        default=2,
        help="hoist-days processed at a time (default 2)",
    )
    parser.add_argument(
        "--memory-budget-gb",
        type=_positive_gb,
        default=None,
        metavar="G",
        help="use fewer --workers if their estimated memory (about 0.9 GB + 0.47 GB a "
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


def _parse_time(text: str) -> dt.datetime:
    """An ISO 8601 time; UTC without an offset."""
    try:
        value = dt.datetime.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"not an ISO 8601 time: {text!r} (e.g. 2026-03-02T06:00, UTC without an offset)"
        ) from None
    return value.replace(tzinfo=dt.UTC) if value.tzinfo is None else value


def _parse_day(text: str) -> dt.date:
    """A day, YYYY-MM-DD."""
    try:
        return dt.date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a day YYYY-MM-DD: {text!r}") from None


def _at_least_one(text: str) -> int:
    """A count of workers: a whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _safe_name(text: str) -> str:
    """A name that becomes a folder or a key (a rig id, a parameter set): a usage error
    unless it is a safe name (:func:`schemas.names.name_problem`)."""
    from schemas.names import name_problem

    problem = name_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return text


def _payload_kg(text: str) -> float:
    """A payload [kg]: a finite number, not negative (0: the conveyance empty)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of kg, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be a finite payload >= 0 kg, got {text}")
    return value


def _positive_gb(text: str) -> float:
    value = float(text)
    if not 0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"must be a positive, finite number of GB, got {text}")
    return value


def _band_member_step(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--band-member-step",
        type=_member_step_seconds,
        default=0.0,
        metavar="S",
        help="solve the uncertainty band's members on S-second means where the pressures "
        "hold still: faster, the band moved by up to ~0.3 %% of the load at single stops "
        "(default 0: at the sensors' rate)",
    )


def _member_step_seconds(text: str) -> float:
    """The step, checked by the settings' own rule (imported here only: the CLI's start
    stays light when the option is not given)."""
    from transforms.compensation_record import CompensationSettings

    value = float(text)
    try:
        CompensationSettings(band_member_step_s=value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"must be 0 or a whole fraction of a second (0.1, 0.2, 0.25, 0.5, 1), got {text}"
        ) from None
    return value


def _positive_minutes(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a positive number of minutes, got {text}")
    return value


def _positive_trips(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number of trips >= 1, got {text}")
    return value


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
    run.add_argument(
        "--payload-kg", type=_payload_kg, default=None, help="known payload at standstill"
    )
    run.add_argument("--no-sanity", action="store_true", help="skip the simulation sanity check")
    run.add_argument(
        "--sanity-trips",
        type=_positive_trips,
        default=None,
        metavar="N",
        help="check N trips sampled in four blocks instead of every trip (faster, and a "
        "block's first trips replay less closely)",
    )
    run.add_argument(
        "--block-minutes",
        type=_positive_minutes,
        default=60.0,
        metavar="M",
        help="samples are processed M minutes at a time: memory grows with M, not with "
        "the period (default 60; results do not depend on it)",
    )
    _band_member_step(run)
    _prefect_option(run)
    run.set_defaults(handler=cmd_run)

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
    _band_member_step(backfill)
    backfill.set_defaults(handler=cmd_backfill)

    nightly = commands.add_parser(
        "nightly", help="every hoist's new raw files since its watermark, processed and landed"
    )
    _fleet_options(nightly)
    add_night_options(nightly)  # shared with python -m pipelines.deploy serve|pool
    nightly.set_defaults(handler=cmd_nightly)


#: ``ropeload paper`` sections (the keys of :data:`pipelines.paper.SECTIONS`, named here
#: so that building the parser imports nothing heavy) and ``all``.
PAPER_SECTIONS = ("table1", "table2", "eq9-10", "section3.1", "all")


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
    paper.set_defaults(handler=cmd_paper)


class _OneLineParser(argparse.ArgumentParser):
    """A usage error is one line on stderr, ``ropeload <command>: <reason> (see
    --help)``, status 2: argparse prints the whole usage block before it."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: {message} (see --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _OneLineParser(
        prog="ropeload",
        description="Rope tensions and hoist loads from hydraulic rope-attachment pressures.",
    )
    commands = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND", parser_class=_OneLineParser
    )

    demo = commands.add_parser(
        "demo", help="the whole job on built-in synthetic data, nothing to configure"
    )
    _data_option(demo)
    demo.add_argument("--seed", type=int, default=7, help="random seed of the synthetic day")
    demo.add_argument("--hours", type=float, default=1.0, help="hours of logs to generate")
    demo.set_defaults(handler=cmd_demo)

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
        "outside its shaft, x beyond its stroke from mid-stroke and speed beyond twice its "
        "winder's max_speed are quarantined; without one only depth above the pithead is "
        "(oil outside -60..200 degC is either way)",
    )
    ingest.add_argument(
        "--complete",
        action="store_true",
        help="the CSV files are finished exports: a last line without a line end is their "
        "last row (by default it is held back, the file 'partial', until the file grows); "
        "a file left partial earlier is read on from where it stopped",
    )
    _prefect_option(ingest)
    ingest.set_defaults(handler=cmd_ingest)

    calibrate = commands.add_parser(
        "calibrate", help="friction-rig recordings (MCAP) -> seal-friction parameter set"
    )
    _data_option(calibrate)
    calibrate.add_argument(
        "--rig", metavar="RIG_ID", type=_safe_name, help="rig to calibrate (default: the only one)"
    )
    calibrate.add_argument(
        "--parameter-set", metavar="NAME", type=_safe_name, help="name of the parameter set"
    )
    calibrate.add_argument(
        "--table1", metavar="FILE", type=Path, help="report OLS lines through paper Table 1 (CSV)"
    )
    calibrate.add_argument(
        "recordings", nargs="*", type=Path, metavar="MCAP", help="recordings to ingest and use"
    )
    calibrate.set_defaults(handler=cmd_calibrate)

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
    discover.set_defaults(handler=cmd_discover)

    query = commands.add_parser("query", help="SQL on the warehouse, read-only")
    _data_option(query)
    query.add_argument("sql", help='e.g. "select * from position_summary"')
    query.add_argument("--format", choices=["table", "csv", "json"], default="table")
    query.set_defaults(handler=cmd_query)
    _add_paper_command(commands)
    for subcommand in commands.choices.values():
        add_log_level_option(subcommand)
    return parser
