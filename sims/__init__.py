"""sims package: the device simulation (issue 3) and its building blocks.

:func:`simulate` runs one trip of a hoist description with effects by contract name;
:func:`paper_scenario_3_2` the paper's four-cylinder load-source scenario;
:mod:`sims.two_cylinder` the paper 2.2 analytic check; :mod:`sims.trips` trip profiles.
"""

from sims.device import OUTPUT_COLUMNS, SimulationResult, paper_scenario_3_2, simulate
from sims.effects import EFFECT_REGISTRY, resolve_effects
from sims.trips import TripProfile, day_schedule, hold, trip

__all__ = [
    "EFFECT_REGISTRY",
    "OUTPUT_COLUMNS",
    "SimulationResult",
    "TripProfile",
    "day_schedule",
    "hold",
    "paper_scenario_3_2",
    "resolve_effects",
    "simulate",
    "trip",
]
