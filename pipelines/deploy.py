"""The nightly deployment: a cron schedule in mine-local time, served by a long-lived process.

Recipe (README, "Running nightly at a mine")::

    prefect server start --host 127.0.0.1 --port 4200            # 1. the API + scheduler
    export PREFECT_API_URL=http://127.0.0.1:4200/api              # 2. every other shell
    python -m pipelines.deploy serve --hoists /etc/ropeload/hoists \\
        --data /srv/ropeload --cron "30 2 * * *"                  # 3. register + serve
    prefect deployment run 'nightly/ropeload-nightly'             # optional: run now

``serve`` registers the deployment ``nightly/<name>`` with a ``Cron`` schedule in the
hoists' IANA time zone (all hoist descriptions must agree, or pass ``--timezone``) and
then executes the scheduled runs in its own process until stopped. Schedules only fire
against a real ``prefect server`` (not the temporary one a bare process starts).

Alternative with a work pool (the server starts runs on a separate worker)::

    prefect work-pool create ropeload --type process
    python -m pipelines.deploy pool --work-pool ropeload --hoists ... --data ...
    prefect worker start --pool ropeload

:func:`write_example_mine` writes a synthetic mine (hoist descriptions + incoming logs)
to try the recipe before real data are connected: ``python -m pipelines.deploy example DIR``.
"""

from __future__ import annotations

from pipelines.prefect_env import apply_prefect_defaults

apply_prefect_defaults()

import argparse  # noqa: E402
import datetime as dt  # noqa: E402
import sys  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from pipelines.hoists import load_hoists  # noqa: E402
from schemas.hoist import EXAMPLE_HOIST, load_hoist  # noqa: E402
from warehouse.store import DataRoot  # noqa: E402

__all__ = [
    "DEFAULT_CRON",
    "DEFAULT_NAME",
    "build_parser",
    "deploy_to_pool",
    "main",
    "mine_timezone",
    "nightly_parameters",
    "nightly_schedule",
    "serve_nightly",
    "write_example_mine",
]

#: 02:30 mine-local time: after the loggers' midnight file roll-over and copy.
DEFAULT_CRON = "30 2 * * *"
DEFAULT_NAME = "ropeload-nightly"
_REPO = Path(__file__).resolve().parents[1]


def mine_timezone(hoists: str | Path, *, data: DataRoot) -> str:
    """The IANA zone shared by every hoist description in ``hoists``."""
    zones = {source.timezone for source in load_hoists(hoists, data=data)}
    if len(zones) != 1:
        raise ValueError(f"{hoists}: hoists in several time zones {sorted(zones)}; pass --timezone")
    return zones.pop()


def nightly_schedule(*, cron: str = DEFAULT_CRON, timezone: str) -> Any:
    """A Prefect ``Cron`` schedule evaluated in ``timezone`` (DST handled by Prefect)."""
    from prefect.schedules import Cron

    return Cron(cron, timezone=timezone)


def nightly_parameters(
    *,
    hoists: str | Path,
    data: str | Path,
    incoming: str | Path | None = None,
    lookback_days: int = 3,
    sanity: bool = True,
) -> dict[str, Any]:
    """Parameters of the nightly deployment (absolute paths: the runner's cwd may differ):
    those of :func:`pipelines.flows.nightly_flow`, as ``ropeload nightly`` takes them."""
    if lookback_days < 0:
        raise ValueError(f"lookback_days must be >= 0, got {lookback_days}")
    return {
        "hoists": str(Path(hoists).absolute()),
        "data": str(Path(data).absolute()),
        "incoming": None if incoming is None else str(Path(incoming).absolute()),
        "lookback_days": lookback_days,
        "sanity": sanity,
    }


def serve_nightly(
    *,
    hoists: str | Path,
    data: str | Path,
    incoming: str | Path | None = None,
    cron: str = DEFAULT_CRON,
    timezone: str | None = None,
    name: str = DEFAULT_NAME,
    max_workers: int = 2,
    dask: str | None = None,
    lookback_days: int = 3,
    sanity: bool = True,
) -> None:
    """Register the nightly deployment with its schedule and serve it (blocks)."""
    from pipelines.flows import nightly_flow
    from pipelines.tasks import task_runner

    zone = timezone or mine_timezone(hoists, data=DataRoot.resolve(data))
    parameters = nightly_parameters(
        hoists=hoists, data=data, incoming=incoming, lookback_days=lookback_days, sanity=sanity
    )
    runner = task_runner(max_workers=max_workers, dask=dask)
    served = nightly_flow.with_options(task_runner=runner)
    served.serve(
        name=name,
        schedules=[nightly_schedule(cron=cron, timezone=zone)],
        parameters=parameters,
        description=f"ropeload nightly run at '{cron}' {zone}",
        tags=["ropeload", "nightly"],
    )


def deploy_to_pool(
    *,
    work_pool: str,
    hoists: str | Path,
    data: str | Path,
    incoming: str | Path | None = None,
    cron: str = DEFAULT_CRON,
    timezone: str | None = None,
    name: str = DEFAULT_NAME,
    lookback_days: int = 3,
    sanity: bool = True,
) -> Any:
    """Register the nightly deployment on a process work pool (source: this checkout)."""
    from prefect import Flow

    zone = timezone or mine_timezone(hoists, data=DataRoot.resolve(data))
    parameters = nightly_parameters(
        hoists=hoists, data=data, incoming=incoming, lookback_days=lookback_days, sanity=sanity
    )
    source = Flow.from_source(source=str(_REPO), entrypoint="pipelines/flows.py:nightly_flow")
    return source.deploy(
        name=name,
        work_pool_name=work_pool,
        schedules=[nightly_schedule(cron=cron, timezone=zone)],
        parameters=parameters,
        description=f"ropeload nightly run at '{cron}' {zone}",
        tags=["ropeload", "nightly"],
        build=False,
        push=False,
        print_next_steps=False,
    )


def write_example_mine(
    root: str | Path,
    *,
    hoists: int = 2,
    days: int = 2,
    first_day: dt.date = dt.date(2026, 3, 2),
    hours: float = 1 / 6,
    trips: int = 2,
    start_hour: float = 12.0,
    sample_rate_hz: float = 100.0,
    seed: int = 1,
) -> tuple[Path, Path]:
    """A synthetic mine under ``root``: ``hoists/`` and ``incoming/<site>/<hoist>/``.

    Hoist ``k`` is the paper's field-test hoist renamed ``shaft-<k>``; each day is
    ``hours`` of logs from ``start_hour`` local time (one CSV per local day). Returns
    (hoists folder, incoming folder).
    """
    from sims.field_day import generate_field_day, write_field_day

    root = Path(root)
    hoist_dir, incoming = root / "hoists", root / "incoming"
    hoist_dir.mkdir(parents=True, exist_ok=True)
    text = EXAMPLE_HOIST.read_text(encoding="utf-8")
    for k in range(1, hoists + 1):
        path = hoist_dir / f"shaft-{k}.toml"
        path.write_text(text.replace('name = "main-shaft"', f'name = "shaft-{k}"'))
        description = load_hoist(path)
        target = incoming / description.hoist.site / description.hoist.name
        for d in range(days):
            day = generate_field_day(
                description,
                date=first_day + dt.timedelta(days=d),
                seed=seed + 1000 * k + d,
                trips=trips,
                hours=hours,
                start_hour=start_hour,
                sample_rate_hz=sample_rate_hz,
            )
            for written in write_field_day(day, target, formats=("csv",)):
                if written.suffix != ".csv":
                    written.unlink()  # truth files are not logger output
    return hoist_dir, incoming


def build_parser() -> argparse.ArgumentParser:
    """``python -m pipelines.deploy serve|pool|example``: serve and pool take the switches
    of ``ropeload nightly`` (:func:`pipelines.night_options.add_night_options`)."""
    from pipelines.cli_parser import data_dir
    from pipelines.night_options import add_night_options

    parser = argparse.ArgumentParser(
        prog="python -m pipelines.deploy", description=__doc__.split("\n")[0]
    )
    commands = parser.add_subparsers(dest="command", required=True)
    for name in ("serve", "pool"):
        sub = commands.add_parser(name, help=f"{name} the nightly deployment")
        sub.add_argument("--hoists", required=True, type=Path, help="folder of hoist descriptions")
        sub.add_argument(
            "--data", required=True, type=lambda text: Path(data_dir(text)), help="data root"
        )
        sub.add_argument("--incoming", type=Path, default=None, help="default <data>/incoming")
        sub.add_argument("--cron", default=DEFAULT_CRON, help=f"default '{DEFAULT_CRON}'")
        sub.add_argument("--timezone", default=None, help="default: the hoists' time zone")
        sub.add_argument("--name", default=DEFAULT_NAME)
        add_night_options(sub)
        if name == "serve":
            sub.add_argument("--workers", type=int, default=2, help="partitions at a time")
            sub.add_argument(
                "--dask",
                metavar="ADDRESS",
                default=None,
                help="run each night on a Dask cluster: a scheduler address or 'local'",
            )
        else:
            sub.add_argument("--work-pool", required=True)
    example = commands.add_parser("example", help="write a synthetic mine to try the recipe")
    example.add_argument("root", type=Path)
    example.add_argument("--days", type=int, default=2)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pipelines.deploy serve|pool|example ...``."""
    args = build_parser().parse_args(argv)
    if args.command == "example":
        hoist_dir, incoming = write_example_mine(args.root, days=args.days)
        sys.stdout.write(f"hoists: {hoist_dir}\nincoming: {incoming}\n")
        return 0
    common = {
        "hoists": args.hoists,
        "data": args.data,
        "incoming": args.incoming,
        "cron": args.cron,
        "timezone": args.timezone,
        "name": args.name,
        "lookback_days": args.lookback_days,
        "sanity": not args.no_sanity,
    }
    if args.command == "serve":
        serve_nightly(**common, max_workers=args.workers, dask=args.dask)
    else:
        deployment_id = deploy_to_pool(work_pool=args.work_pool, **common)
        sys.stdout.write(f"deployment {deployment_id} on work pool {args.work_pool}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
