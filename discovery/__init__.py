"""Model-discrepancy discovery: which named effect (contract section 4) is missing.

:mod:`discovery.planning` -- the measured trips of a record prepared for replay through
the device simulation (:mod:`sims.replay`), with :mod:`discovery.record`,
:mod:`discovery.segmentation` and :mod:`discovery.rope_damping`.
:mod:`discovery.library` -- one candidate term per contract effect, each able to
switch its effect on in the device simulation and to move its parameters (the terms in
:mod:`discovery.effect_terms`).
:mod:`discovery.selection` -- residual test against the noise, scoring with
re-tuning, information criterion + trip bootstrap, ambiguity, iteration: the
:class:`EffectSelector` (pysindy-like ``fit`` / ``coef_`` / ``support_`` /
``complexity``) and :func:`discover_effects`; its steps in :mod:`discovery.iteration`,
:mod:`discovery.columns`, :mod:`discovery.normal_equations`, :mod:`discovery.ranking`,
:mod:`discovery.bootstrap`, :mod:`discovery.refit`, :mod:`discovery.gap`.
:mod:`discovery.record_rereading` -- :func:`discover_in_record`: discovery over a
landed record, planning it again (ropes, motion read anew) after each effect added.
:mod:`discovery.cases` -- synthetic hidden-effect cases for tests and benchmarks.

``discovery`` imports ``sims``; ``sims`` never imports ``discovery``. The package's
interface is what this module exports; a name one module of the package imports from
another has no leading underscore and is in that module's ``__all__`` (underscore names
stay inside their module).
"""

from discovery.library import EFFECT_LIBRARY, EffectLibrary, EffectTerm
from discovery.planning import plan_replay
from discovery.record_rereading import discover_in_record
from discovery.results import DiscoveryResult, Finding
from discovery.selection import EffectSelector, discover_effects

__all__ = [
    "EFFECT_LIBRARY",
    "DiscoveryResult",
    "EffectLibrary",
    "EffectSelector",
    "EffectTerm",
    "Finding",
    "discover_effects",
    "discover_in_record",
    "plan_replay",
]
