"""The per-engine table of how the diagnosis' effects are realised: :func:`effect_realisations`.

The embedded engine's realisations are :data:`~bedstruct.engines.EMBEDDED_REALISATIONS`;
each external dialect states its own (:attr:`~bedstruct.engines.Dialect.realisations`).
"""

from __future__ import annotations

from ._dialect import EMBEDDED_REALISATIONS, Realisation
from ._registry import _DIALECTS, ENGINE_NAMES

__all__ = ["effect_realisations"]


def effect_realisations() -> dict:
    """Per catalogue effect, how each engine realises it: ``{effect: {engine: Realisation}}``.

    The engines are ``embedded`` (:data:`~bedstruct.engines.EMBEDDED_REALISATIONS`) and
    every external dialect (:attr:`~bedstruct.engines.Dialect.realisations`); a
    :class:`~bedstruct.engines.Realisation` says how, or why not and what to run instead.

    Examples
    --------
    >>> table = effect_realisations()
    >>> [e for e, r in table["capillary_bridges"].items() if r.realised]
    ['embedded', 'liggghts']
    """
    engines = {"embedded": EMBEDDED_REALISATIONS,
               **{name: _DIALECTS[name].realisations for name in ENGINE_NAMES if name in _DIALECTS}}
    missing = Realisation(refused="no realisation is stated")
    return {effect: {eng: table.get(effect, missing) for eng, table in engines.items()}
            for effect in EMBEDDED_REALISATIONS}
