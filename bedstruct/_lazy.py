"""Helpers for subpackages that re-export the ``__all__`` of their modules."""

from __future__ import annotations

import importlib
from types import ModuleType


def collect(package: str, modules: list[str], namespace: dict) -> list[str]:
    """Import ``package.<m>`` for each name in ``modules`` and copy its ``__all__``.

    A module that does not exist yet is skipped; any other import error is
    raised, so a broken module is never hidden.
    """
    exported: list[str] = []
    for name in modules:
        full = f"{package}.{name}"
        try:
            mod: ModuleType = importlib.import_module(full)
        except ModuleNotFoundError as exc:
            if exc.name == full:
                continue
            raise
        for attr in getattr(mod, "__all__", []):
            namespace[attr] = getattr(mod, attr)
            exported.append(attr)
    return exported
