"""The contact model every deck takes: the embedded engine's
:class:`~bedstruct.dem.ContactModel` of one particle type (default: the seed's,
:func:`~bedstruct.dem.seed_contact_model`), and gravity where a deck has it.

:func:`one_type_model` checks a model for what every deck needs; :func:`coefficient`
reads one of its particle-particle or particle-wall values. Each dialect refuses by
name what its engine cannot realise (:meth:`~bedstruct.engines.Dialect.deck_model`).
"""

from __future__ import annotations

import math

from ..errors import ConfigError

__all__ = ["one_type_model", "coefficient", "check_gravity"]

#: Coefficients read from the model's per-type-pair tables.
_TABLES = ("restitution", "friction", "rolling_friction", "cohesion")
#: Values of the particles' (and the walls') material.
_MATERIAL = ("youngs_modulus", "poisson_ratio", "density")


def one_type_model(model, engine: str):
    """``model`` checked for the decks of ``engine`` (None: the seed's model).

    Returns
    -------
    bedstruct.dem.ContactModel

    Raises
    ------
    TypeError
        For an object that is not a :class:`~bedstruct.dem.ContactModel`.
    bedstruct.errors.ConfigError
        For more than one particle type, a zero restitution, or switches the decks do not
        write (``tangential_damping`` off, ``limit_force`` on), each named.
    """
    # the engine's kernels load with bedstruct.dem: imported when a deck is written
    from ..dem import ContactModel, seed_contact_model
    if model is None:
        return seed_contact_model()
    if not isinstance(model, ContactModel):
        raise TypeError(f"the contact model of a {engine} deck must be a bedstruct.dem "
                        f"ContactModel (e.g. seed_contact_model()); got {type(model).__name__}")
    if model.n_types != 1:
        raise ConfigError(f"{engine} decks take one particle type; the ContactModel has "
                          f"{model.n_types} (`materials`)")
    t = model.tables()
    if not (t.restitution[:1, :2] > 0.0).all():
        raise ConfigError(f"{engine} decks need `restitution` and `wall_restitution` > 0; got "
                          f"{t.restitution[0, 0]!r} and {t.restitution[0, 1]!r}")
    if not model.tangential_damping:
        raise ConfigError(f"{engine} decks write the tangential dashpot always; "
                          "`tangential_damping` = False is the embedded engine's option")
    if model.limit_force:
        raise ConfigError(f"{engine} decks do not clip the normal force; `limit_force` = True is "
                          "the embedded engine's option")
    return model


def coefficient(model, name: str, *, wall: bool = False) -> float:
    """Particle-particle (or, with ``wall``, particle-wall) value of ``name`` in SI.

    ``name`` is a coefficient (``restitution``, ``friction``, ``rolling_friction`` (0
    when ``rolling_model`` is ``"none"``), ``cohesion``) or a material value
    (``youngs_modulus``, ``poisson_ratio``: the wall material's with ``wall``;
    ``density``: the particles'). Particle type 1 of a one-type model.

    Examples
    --------
    >>> from bedstruct.dem import Material, seed_contact_model
    >>> m = seed_contact_model(wall_material=Material(2e8, 0.25), wall_friction=0.6)
    >>> coefficient(m, "friction"), coefficient(m, "friction", wall=True)
    (0.4, 0.6)
    >>> coefficient(m, "youngs_modulus", wall=True)
    200000000.0
    """
    if name in _MATERIAL:
        mat = (model.wall_material or model.materials[0]) if wall and name != "density" \
            else model.materials[0]
        return float(getattr(mat, name))
    if name not in _TABLES:
        raise ValueError(f"unknown contact value {name!r}; expected one of "
                         f"{', '.join(_TABLES + _MATERIAL)}")
    if name == "rolling_friction" and model.rolling_model == "none":
        return 0.0
    return float(getattr(model.tables(), name)[0, model.n_types if wall else 0])


def check_gravity(gravity) -> float:
    """``gravity`` (m/s^2, along -z; 0 switches it off) as a float, or ValueError."""
    g = float(gravity)
    if not (math.isfinite(g) and g >= 0.0):
        raise ValueError(f"`gravity` must be a magnitude >= 0 in m/s^2 (along -z); got {gravity!r}")
    return g
