"""The external engines by name: :func:`dialect` gives the dialect object of one.

Each dialect module registers its class here (:func:`register`) when the package
is imported; nothing here knows an engine's commands.
"""

from __future__ import annotations

from ..errors import ConfigError

__all__ = ["ENGINE_NAMES", "dialect", "register"]

#: Names of the external engines bedstruct writes decks for.
ENGINE_NAMES = ("liggghts", "lammps")

_DIALECTS: dict = {}


def register(cls):
    """Class decorator: make ``cls`` (a dialect with a ``name``) the dialect of ``cls.name``."""
    if cls.name not in ENGINE_NAMES:
        raise ValueError(f"no external engine is called {cls.name!r}")
    _DIALECTS[cls.name] = cls
    return cls


def dialect(engine, **options):
    """The dialect object of ``engine``.

    Parameters
    ----------
    engine : {"liggghts", "lammps"} or Dialect
        An engine name, or a dialect (returned as it is when no ``options`` are
        given, else a copy with them).
    **options
        Dialect options, e.g. LAMMPS' ``cohesion_model``, ``reference_radius`` and
        ``reference_overlap`` (:class:`~bedstruct.engines.LammpsDialect`) or LIGGGHTS'
        ``liquid_bridges``; None keeps the dialect's value. LAMMPS' mapping options
        are ignored by LIGGGHTS; any other option a dialect lacks is refused
        (:meth:`~bedstruct.engines.Dialect.with_options`).

    Returns
    -------
    Dialect

    Raises
    ------
    bedstruct.errors.ConfigError
        For another name, or an option the engine cannot realise.

    Examples
    --------
    >>> from bedstruct.engines import dialect
    >>> dialect("lammps").name, dialect("liggghts").atom_style
    ('lammps', 'granular')
    """
    if isinstance(engine, str):
        if engine not in _DIALECTS:
            raise ConfigError(f"`engine` must be 'liggghts' or 'lammps'; got {engine!r}")
        return _DIALECTS[engine]().with_options(**options)
    if engine is None or not hasattr(engine, "model_lines"):
        raise ConfigError(f"`engine` must be 'liggghts' or 'lammps'; got {engine!r}")
    return engine.with_options(**options) if options else engine

