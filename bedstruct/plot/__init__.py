"""Figures. Every function returns matplotlib ``Figure``/``Axes`` objects and
never shows or saves them (the caller decides)."""

from .._lazy import collect as _collect

__all__ = _collect(__name__, [
    "metrics", "fabric", "heat", "workflows", "diagnose",
], globals())
