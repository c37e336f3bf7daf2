"""Model-discrepancy discovery: which named effect (contract section 4) is missing.

:mod:`sims.discovery.library` -- one candidate term per contract effect, each able to
switch its effect on in the device simulation and to move its parameters.
:mod:`sims.discovery.selection` -- residual test against the noise, scoring with
re-tuning, information criterion + trip bootstrap, ambiguity, iteration.
"""

from sims.discovery.library import EFFECT_LIBRARY, EffectLibrary, EffectTerm
from sims.discovery.selection import DiscoveryResult, Finding, discover_effects

__all__ = [
    "EFFECT_LIBRARY",
    "DiscoveryResult",
    "EffectLibrary",
    "EffectTerm",
    "Finding",
    "discover_effects",
]
