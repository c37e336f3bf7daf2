"""The switches of a night, defined once for ``ropeload nightly`` and for the deployment
``python -m pipelines.deploy serve|pool`` (which runs the same night on a schedule).

Kept apart from :mod:`pipelines.nightly` so that building the CLI's parser imports
nothing heavy (``ropeload --help`` and every other command start fast).
"""

from __future__ import annotations

import argparse

__all__ = ["DEFAULT_LOOKBACK_DAYS", "add_night_options"]

#: Not-done days re-run before each hoist's watermark (a failed night heals itself).
DEFAULT_LOOKBACK_DAYS = 3


def _non_negative(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def add_night_options(parser: argparse.ArgumentParser) -> None:
    """``--lookback-days N`` and ``--no-sanity``."""
    parser.add_argument(
        "--lookback-days",
        type=_non_negative,
        default=DEFAULT_LOOKBACK_DAYS,
        metavar="N",
        help="also re-run not-done days this far before each hoist's watermark "
        f"(default {DEFAULT_LOOKBACK_DAYS})",
    )
    parser.add_argument("--no-sanity", action="store_true", help="skip the simulation sanity check")
