"""The effect library: one candidate term per named effect of contract section 4.

In the shape of a SINDy candidate library (Brunton, Proctor & Kutz 2016, PNAS 113(15)
3932-3937, doi:10.1073/pnas.1517384113; the pysindy ``feature_library`` API): a library
knows its terms (:meth:`EffectLibrary.get_feature_names`), libraries combine with
``+``, and each term can be evaluated. Here a term is not a column of a function of the
state but a physical effect of the device simulation (:mod:`sims.device`): it switches
its effect on (:attr:`EffectTerm.name` in the ``effects`` set) and maps a small vector of
coordinates to the effect's parameters (:meth:`EffectTerm.parameters`), so the
selection (:mod:`discovery.selection`) can fit it by Gauss-Newton on finite-
difference columns of the simulated pressures.

The terms themselves, their coordinates and finite-difference steps are in
:mod:`discovery.effect_terms`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from discovery.effect_terms import EffectTerm, Params, effect_terms
from schemas.effects import EFFECT_NAMES
from schemas.hoist import HoistDescription

__all__ = ["EFFECT_LIBRARY", "EffectLibrary", "EffectTerm", "term_parameters"]


class EffectLibrary:
    """An ordered collection of :class:`EffectTerm` (pysindy-style library).

    ``fit(hoist)`` sizes the per-sensor and per-rope terms to the hoist;
    ``get_feature_names()`` lists the term names; ``lib_a + lib_b`` concatenates.
    """

    def __init__(self, terms: Iterable[EffectTerm]) -> None:
        self.terms: dict[str, EffectTerm] = {}
        for term in terms:
            if term.name not in EFFECT_NAMES:
                raise ValueError(f"unknown effect {term.name!r}; valid: {', '.join(EFFECT_NAMES)}")
            self.terms[term.name] = term
        self.n_terms_ = len(self.terms)

    def fit(self, hoist: HoistDescription) -> EffectLibrary:
        """Size per-sensor / per-rope terms to ``hoist.ropes_n``; returns self."""
        n = hoist.ropes_n
        sized = []
        for term in self.terms.values():
            if term.name in ("sensor_offset", "sensor_gain"):
                stem = "offset_pa" if term.name == "sensor_offset" else "gain"
                term = _resize(term, tuple(f"{stem}[{i}]" for i in range(1, n + 1)))
            elif term.name == "groove_wear":
                term = _resize(
                    term, tuple(f"groove_radius_deviation_m[{i}]" for i in range(2, n + 1))
                )
            sized.append(term)
        self.terms = {t.name: t for t in sized}
        self.n_terms_ = len(self.terms)
        return self

    def get_feature_names(self) -> list[str]:
        return list(self.terms)

    def __getitem__(self, name: str) -> EffectTerm:
        return self.terms[name]

    def __contains__(self, name: object) -> bool:
        return name in self.terms

    def __add__(self, other: EffectLibrary) -> EffectLibrary:
        return EffectLibrary([*self.terms.values(), *other.terms.values()])

    def candidates(self, model_effects: Iterable[str]) -> list[str]:
        """Terms not in the model whose requirements are in it, in contract order."""
        model = set(model_effects)
        return [
            name
            for name, term in self.terms.items()
            if name not in model and all(r in model for r in term.requires)
        ]


def _resize(term: EffectTerm, names: tuple[str, ...]) -> EffectTerm:
    return EffectTerm(
        term.name,
        names,
        (term.steps[0],) * len(names),
        term.requires,
        term.excitation,
        term.get,
        term.set,
        term.analytic,
        term.prior_sd,
        term.start_amplitudes,
        term.start_scales,
        term.start_shifts,
    )


def term_parameters(
    hoist: HoistDescription,
    overrides: Mapping[str, Mapping[str, Any]] | None,
    effects: Iterable[str],
) -> Params:
    """``overrides`` restricted to the switched-on ``effects`` (for ``simulate``)."""
    on = set(effects)
    return {k: dict(v) for k, v in (overrides or {}).items() if k in on}


#: The full library: every contract effect, in contract order.
EFFECT_LIBRARY = EffectLibrary(effect_terms().values())
