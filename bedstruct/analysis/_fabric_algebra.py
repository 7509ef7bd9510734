"""Tensor algebra of the fabric tensors: symmetrisation, the isotropic rank-4
tensor, deviatoric parts, and the second and third kinds from the moments.

Implementation module of :mod:`bedstruct.analysis.fabric` (import from there).
"""

from __future__ import annotations

import numpy as np

__all__ = ["sym_delta_tensor", "isotropic_rank4", "deviatoric_rank4"]

_DELTA = np.eye(3)


def sym_delta_tensor(t2) -> np.ndarray:
    """Full symmetrisation :math:`\\delta_{(ij} T_{kl)}` of a symmetric (3, 3) tensor.

    .. math::

        \\delta_{(ij}T_{kl)} = \\tfrac16(\\delta_{ij}T_{kl} + \\delta_{ik}T_{jl} + \\delta_{il}T_{jk}
        + \\delta_{jk}T_{il} + \\delta_{jl}T_{ik} + \\delta_{kl}T_{ij})

    Parameters
    ----------
    t2 : (3, 3) array_like of float
        A symmetric tensor.

    Returns
    -------
    (3, 3, 3, 3) ndarray of float

    Examples
    --------
    >>> s = sym_delta_tensor(np.eye(3))   # = isotropic_rank4()
    >>> float(s[0, 0, 0, 0]), float(s[0, 0, 1, 1]), float(s[0, 1, 0, 1])
    (1.0, 0.333..., 0.333...)
    """
    t = np.asarray(t2, dtype=np.float64)
    d = _DELTA
    return (np.einsum("ij,kl->ijkl", d, t) + np.einsum("ik,jl->ijkl", d, t)
            + np.einsum("il,jk->ijkl", d, t) + np.einsum("jk,il->ijkl", d, t)
            + np.einsum("jl,ik->ijkl", d, t) + np.einsum("kl,ij->ijkl", d, t)) / 6.0


def isotropic_rank4() -> np.ndarray:
    """:math:`\\delta_{(ij}\\delta_{kl)} = (\\delta_{ij}\\delta_{kl} + \\delta_{ik}\\delta_{jl} + \\delta_{il}\\delta_{jk})/3`.

    The rank-4 analogue of the identity: contracted with ``n n n n`` it
    gives 1 for every unit vector, and it is the second-kind tensor
    :math:`F_{ijkl}` of an isotropic distribution.

    Examples
    --------
    >>> n = np.array([0.6, 0.0, 0.8])
    >>> float(np.einsum("ijkl,i,j,k,l->", isotropic_rank4(), n, n, n, n))
    1.0...
    """
    d = _DELTA
    return (np.einsum("ij,kl->ijkl", d, d) + np.einsum("ik,jl->ijkl", d, d)
            + np.einsum("il,jk->ijkl", d, d)) / 3.0


def deviatoric_rank4(t4) -> np.ndarray:
    """Deviatoric (fully traceless) part of a fully symmetric rank-4 tensor.

    .. math::

        T'_{ijkl} = T_{ijkl} - \\tfrac67 \\delta_{(ij}T_{kl)mm} + \\tfrac{3}{35}
        \\delta_{(ij}\\delta_{kl)} T_{mmnn}

    Parameters
    ----------
    t4 : (3, 3, 3, 3) array_like of float
        Fully symmetric tensor.

    Returns
    -------
    (3, 3, 3, 3) ndarray of float
        Traceless on every pair of indices.

    Examples
    --------
    >>> t = deviatoric_rank4(isotropic_rank4())
    >>> float(np.abs(t).max()) < 1e-15
    True
    """
    t4 = np.asarray(t4, dtype=np.float64)
    t2 = np.einsum("ijkk->ij", t4)
    t0 = float(np.trace(t2))
    return t4 - (6.0 / 7.0) * sym_delta_tensor(t2) + (3.0 / 35.0) * t0 * isotropic_rank4()


def _second_kind(n2, n4):
    f2 = 7.5 * (n2 - _DELTA / 5.0)
    f4 = (315.0 / 8.0) * (n4 - (2.0 / 3.0) * sym_delta_tensor(n2) + isotropic_rank4() / 21.0)
    return f2, f4


def _third_kind(n2, n4):
    d2 = 7.5 * (n2 - _DELTA / 3.0)
    d4 = (315.0 / 8.0) * (n4 - (6.0 / 7.0) * sym_delta_tensor(n2)
                          + (3.0 / 35.0) * isotropic_rank4())
    return d2, d4


def _readonly(a):
    a = np.ascontiguousarray(a, dtype=np.float64)
    a.setflags(write=False)
    return a
