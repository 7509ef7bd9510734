"""Fabric tensors of contact normals (Kanatani 1984), ranks 2 and 4, three kinds.

For unit directions :math:`n^{(a)}` with weights :math:`w_a` (1 by default)
the tensors of the *first kind* (moment tensors) are the weighted means

.. math::

    N_{ij} = \\langle n_i n_j \\rangle, \\qquad N_{ijkl} = \\langle n_i n_j n_k n_l \\rangle .

A contact's direction ``n`` and ``-n`` give the same even-rank products, so
these tensors are antipodally symmetric by construction. The *second kind*
(fabric tensors) and the *third kind* (deviatoric tensors) are

.. math::

    F_{ij} = \\tfrac{15}{2}\\left(N_{ij} - \\tfrac15 \\delta_{ij}\\right), \\quad
    F_{ijkl} = \\tfrac{315}{8}\\left(N_{ijkl} - \\tfrac23 \\delta_{(ij}N_{kl)}
               + \\tfrac1{21}\\delta_{(ij}\\delta_{kl)}\\right),

    D_{ij} = \\tfrac{15}{2}\\left(N_{ij} - \\tfrac13 \\delta_{ij}\\right), \\quad
    D_{ijkl} = \\tfrac{315}{8}\\left(N_{ijkl} - \\tfrac67 \\delta_{(ij}N_{kl)}
               + \\tfrac3{35}\\delta_{(ij}\\delta_{kl)}\\right),

with the full symmetrisation
:math:`\\delta_{(ij}N_{kl)} = (\\delta_{ij}N_{kl} + \\delta_{ik}N_{jl} + \\delta_{il}N_{jk}
+ \\delta_{jk}N_{il} + \\delta_{jl}N_{ik} + \\delta_{kl}N_{ij})/6` and
:math:`\\delta_{(ij}\\delta_{kl)} = (\\delta_{ij}\\delta_{kl} + \\delta_{ik}\\delta_{jl}
+ \\delta_{il}\\delta_{jk})/3`. They approximate the direction density
(per unit solid angle, integrating to 1 over the sphere)

.. math::

    f(n) = \\frac{1}{4\\pi}\\left(1 + D_{ij} n_i n_j + D_{ijkl} n_i n_j n_k n_l\\right)
         = \\frac{1}{4\\pi} F_{ijkl} n_i n_j n_k n_l ,

which is the truncation at degree 4 of the density's spherical-harmonic
series (see :mod:`bedstruct.analysis.harmonics` and ``docs/fabric.md`` for
the derivation). All quantities are dimensionless.

References
----------
K. Kanatani, "Distribution of directional data and fabric tensors",
Int. J. Eng. Sci. 22 (1984) 149-164, https://doi.org/10.1016/0020-7225(84)90090-9
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from . import _fabric_kernels as _k

__all__ = [
    "FabricTensors", "fabric_tensors", "fabric_density", "projected_density",
    "sample_directions", "contact_regions", "RegionFabric", "region_fabric",
    "LammpsFabric", "lammps_fabric", "lammps_voigt", "fabric_table",
    "deviatoric_rank4", "sym_delta_tensor", "isotropic_rank4",
]

log = logging.getLogger(__name__)

_DELTA = np.eye(3)
_REGION_NAMES_3 = ("start", "centre", "end")


# --------------------------------------------------------------------------- algebra
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


# --------------------------------------------------------------------------- result
@dataclass(frozen=True)
class FabricTensors:
    """Fabric tensors of ranks 2 and 4 and kinds 1-3 of one set of directions.

    All tensors are dimensionless and fully symmetric. Build with
    :func:`fabric_tensors` (from directions) or :meth:`from_moments`.

    Attributes
    ----------
    N2, N4 : (3, 3), (3, 3, 3, 3) ndarray
        Moment tensors (first kind), weighted means of ``n n`` and ``n n n n``.
    F2, F4 : (3, 3), (3, 3, 3, 3) ndarray
        Fabric tensors of the second kind; ``F4 :: nnnn / (4 pi)`` is the
        rank-4 approximation of the density, ``F2 : nn / (4 pi)`` the rank-2 one.
    D2, D4 : (3, 3), (3, 3, 3, 3) ndarray
        Deviatoric tensors (third kind), traceless.
    n_contacts : int
        Number of directions used (rows of zero length excluded).
    total_weight : float
        Sum of the weights (``n_contacts`` when unweighted).
    eigenvalues : (3,) ndarray
        Eigenvalues of ``N2`` in descending order (they sum to 1).
    eigenvectors : (3, 3) ndarray
        Matching unit eigenvectors as columns.
    anisotropy : float
        :math:`a = \\sqrt{\\tfrac32 D_{ij} D_{ij}}`, the rank-2 anisotropy of
        Rothenburg & Bathurst / Ouadfel & Rothenburg (0 for isotropic; for
        ``f = (1 + a (3 (e.n)^2 - 1)/3 ... )`` style axisymmetric deviators
        ``D = a (3 e e - I) / 3`` it returns ``a``).
    anisotropy_rank4 : float
        :math:`\\sqrt{D_{ijkl} D_{ijkl}}`, the Frobenius norm of the rank-4
        deviator.

    .. versionadded:: 0.1
    """

    N2: np.ndarray
    N4: np.ndarray
    F2: np.ndarray
    F4: np.ndarray
    D2: np.ndarray
    D4: np.ndarray
    n_contacts: int
    total_weight: float
    eigenvalues: np.ndarray = field(repr=False)
    eigenvectors: np.ndarray = field(repr=False)
    anisotropy: float
    anisotropy_rank4: float

    @classmethod
    def from_moments(cls, N2, N4, *, n_contacts: int = 0, total_weight: float | None = None
                     ) -> "FabricTensors":
        """Build every kind from the moment tensors ``N2`` (3, 3) and ``N4`` (3, 3, 3, 3).

        Examples
        --------
        >>> t = FabricTensors.from_moments(np.eye(3) / 3, isotropic_rank4() / 5)
        >>> np.allclose(t.F2, np.eye(3)), np.allclose(t.D2, 0), np.allclose(t.D4, 0)
        (True, True, True)
        """
        n2 = np.asarray(N2, dtype=np.float64)
        n4 = np.asarray(N4, dtype=np.float64)
        if n2.shape != (3, 3) or n4.shape != (3, 3, 3, 3):
            raise ValueError(f"`N2` must have shape (3, 3) and `N4` (3, 3, 3, 3); "
                             f"got {n2.shape} and {n4.shape}")
        f2, f4 = _second_kind(n2, n4)
        d2, d4 = _third_kind(n2, n4)
        w, v = np.linalg.eigh(0.5 * (n2 + n2.T))
        order = np.argsort(w)[::-1]
        w, v = w[order], v[:, order]
        # a deterministic sign: largest-magnitude component of each eigenvector positive
        idx = np.argmax(np.abs(v), axis=0)
        v = v * np.sign(v[idx, np.arange(3)])
        return cls(N2=_readonly(n2), N4=_readonly(n4), F2=_readonly(f2), F4=_readonly(f4),
                   D2=_readonly(d2), D4=_readonly(d4), n_contacts=int(n_contacts),
                   total_weight=float(n_contacts if total_weight is None else total_weight),
                   eigenvalues=_readonly(w), eigenvectors=_readonly(v),
                   anisotropy=float(math.sqrt(1.5 * float(np.sum(d2 * d2)))),
                   anisotropy_rank4=float(math.sqrt(float(np.sum(d4 * d4)))))

    def density(self, directions, *, rank: int = 4) -> np.ndarray:
        """Shortcut for :func:`fabric_density` ``(self, directions, rank=rank)``."""
        return fabric_density(self, directions, rank=rank)

    def rotated(self, rotation) -> "FabricTensors":
        """The tensors of the directions rotated by the (3, 3) orthogonal matrix ``rotation``.

        Examples
        --------
        >>> t = fabric_tensors([[1.0, 0.0, 0.0]])
        >>> r = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        >>> t.rotated(r).N2.round(12).tolist()
        [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]]
        """
        r = np.asarray(rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.allclose(r @ r.T, _DELTA, atol=1e-10):
            raise ValueError(f"`rotation` must be an orthogonal (3, 3) matrix; got shape {r.shape}")
        n2 = np.einsum("ia,jb,ab->ij", r, r, self.N2)
        n4 = np.einsum("ia,jb,kc,ld,abcd->ijkl", r, r, r, r, self.N4, optimize=True)
        return FabricTensors.from_moments(n2, n4, n_contacts=self.n_contacts,
                                          total_weight=self.total_weight)


# --------------------------------------------------------------------------- validation
def _as_directions(normals, name="normals") -> np.ndarray:
    if hasattr(normals, "normals") and hasattr(normals, "branch"):
        normals = normals.normals
    arr = np.asarray(normals, dtype=np.float64)
    if arr.ndim == 1 and arr.size == 3:
        arr = arr.reshape(1, 3)
    if arr.ndim == 1 and arr.size == 0:
        arr = arr.reshape(0, 3)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"`{name}` must have shape (M, 3); got {arr.shape}")
    return np.ascontiguousarray(arr)


def _resolve_weights(source, weights, m):
    """Weights array (M,) or None; strings look up per-contact fields of a Contacts object."""
    if weights is None:
        return None
    if isinstance(weights, str):
        if not (hasattr(source, "branch") and hasattr(source, "normals")):
            raise TypeError(f"`weights={weights!r}` needs a Contacts object as first argument; "
                            f"got {type(source).__name__}")
        key = weights.lower()
        if key in ("force_normal", "normal_force", "force"):
            fn = source.force_normal
            if fn is None:
                raise ValueError("`weights='force_normal'` needs Contacts.force_normal; "
                                 "these contacts have no forces (read a dump local file)")
            weights = np.sqrt(np.einsum("ij,ij->i", fn, fn))
        elif key in ("contact_area", "area"):
            weights = source.contact_area
        elif key in ("branch_length", "branch", "distance"):
            weights = source.distance
        else:
            raise ValueError(f"unknown `weights` {weights!r}; expected an array or one of "
                             f"'force_normal', 'contact_area', 'branch_length'")
    w = np.ascontiguousarray(weights, dtype=np.float64)
    if w.ndim == 0:
        w = np.full(m, float(w))
    if w.shape != (m,):
        raise ValueError(f"`weights` must have shape (M,) matching the directions (M={m}); "
                         f"got {w.shape}")
    if m and not np.all(np.isfinite(w)):
        raise ValueError("`weights` must be finite")
    if m and w.min() < 0:
        raise ValueError(f"`weights` must be non-negative; got minimum {w.min()}")
    return w


def _n_chunks(m: int) -> int:
    from .._numba import get_num_threads
    return int(max(1, min(4 * get_num_threads(), m // 4096 + 1)))


# --------------------------------------------------------------------------- main entry
def fabric_tensors(normals, weights=None) -> FabricTensors:
    """Fabric tensors of ranks 2 and 4 (kinds 1, 2, 3) of a set of directions.

    Parameters
    ----------
    normals : (M, 3) array_like of float, or Contacts
        Contact normals (any length; each row is normalised), or a
        :class:`~bedstruct.Contacts` whose ``normals`` are used. ``n`` and
        ``-n`` are equivalent. Rows of zero length (coincident centres) are
        skipped and logged.
    weights : (M,) array_like of float or str, optional
        Non-negative per-contact weights (e.g. normal-force magnitude or
        contact area). With a Contacts object the strings
        ``"force_normal"`` (``|force_normal|``), ``"contact_area"`` and
        ``"branch_length"`` (``|branch|``) select its fields. Default: all 1.

    Returns
    -------
    FabricTensors
        ``N2, N4, F2, F4, D2, D4`` (dimensionless), eigen-decomposition of
        ``N2`` and scalar anisotropies.

    Raises
    ------
    ValueError
        Bad shapes, negative or non-finite weights, no usable direction,
        or all weights zero.

    Notes
    -----
    With :math:`W = \\sum_a w_a`,
    :math:`N_{ij} = W^{-1}\\sum_a w_a n_i^a n_j^a` and likewise for
    :math:`N_{ijkl}`; the other kinds follow from the module formulas.
    Uniform weights give exactly the unweighted tensors. For spheres the
    branch vector is parallel to the normal, so the *branch* fabric is the
    ``weights="branch_length"`` tensor and the force fabric the
    ``weights="force_normal"`` tensor (Ouadfel & Rothenburg 2001).

    Examples
    --------
    The six contacts of a simple cubic lattice (each once, ``n`` or ``-n``):

    >>> t = fabric_tensors([[1, 0, 0], [0, -1, 0], [0, 0, 2]])
    >>> t.N2.round(6).tolist()
    [[0.333333, 0.0, 0.0], [0.0, 0.333333, 0.0], [0.0, 0.0, 0.333333]]
    >>> bool(np.allclose(t.D2, 0)), bool(np.allclose(t.F2, np.eye(3)))
    (True, True)
    >>> float(t.D4[0, 0, 0, 0])      # cubic symmetry shows at rank 4
    5.25
    """
    arr = _as_directions(normals)
    m = arr.shape[0]
    w = _resolve_weights(normals, weights, m)
    n_chunks = _n_chunks(m)
    out = np.zeros((n_chunks, _k.N_MOMENT_COLUMNS))
    _k.moment_sums(arr, w if w is not None else np.empty(0), w is not None, n_chunks, out)
    sums = out.sum(axis=0)
    n_bad = int(sums[1])
    n_used = m - n_bad
    if n_bad:
        log.info("fabric_tensors: skipped %d directions of zero length or non-finite", n_bad)
    if n_used == 0:
        raise ValueError(f"`normals` has no usable direction (M={m}, {n_bad} of zero length "
                         f"or non-finite)")
    total = float(sums[0])
    if not total > 0:
        raise ValueError("`weights` sum to zero over the usable directions")
    n2 = _assemble_n2(sums[2:8] / total)
    n4 = _assemble_n4(sums[8:23] / total)
    return FabricTensors.from_moments(n2, n4, n_contacts=n_used, total_weight=total)


def _assemble_n2(v6):
    n2 = np.empty((3, 3))
    for k, (i, j) in enumerate(_k.MONO2):
        n2[i, j] = n2[j, i] = v6[k]
    return n2


def _mono4_index():
    lookup = {tuple(e): k for k, e in enumerate(_k.MONO4.tolist())}
    idx = np.empty((3, 3, 3, 3), dtype=np.int64)
    for i, j, k, l in np.ndindex(3, 3, 3, 3):
        e = [0, 0, 0]
        for a in (i, j, k, l):
            e[a] += 1
        idx[i, j, k, l] = lookup[tuple(e)]
    return idx


_MONO4_INDEX = _mono4_index()


def _assemble_n4(v15):
    return np.asarray(v15, dtype=np.float64)[_MONO4_INDEX]


# --------------------------------------------------------------------------- density
def _unit_rows(directions):
    d = np.asarray(directions, dtype=np.float64)
    shape = d.shape[:-1]
    if d.shape[-1:] != (3,):
        raise ValueError(f"`directions` must have shape (..., 3); got {d.shape}")
    d = d.reshape(-1, 3)
    norm = np.sqrt(np.einsum("ij,ij->i", d, d))
    if np.any(norm == 0):
        raise ValueError("`directions` contains a zero vector")
    return d / norm[:, None], shape


def fabric_density(tensors: FabricTensors, directions, *, rank=4) -> np.ndarray:
    """The direction density approximated by the fabric tensors, per steradian.

    Parameters
    ----------
    tensors : FabricTensors
    directions : (..., 3) array_like of float
        Directions (normalised here).
    rank : {2, 4, "difference"}
        ``2``: :math:`f_2 = (1 + D_{ij}n_in_j)/(4\\pi)`; ``4``:
        :math:`f_4 = (1 + D_{ij}n_in_j + D_{ijkl}n_in_jn_kn_l)/(4\\pi)`;
        ``"difference"``: :math:`f_4 - f_2 = D_{ijkl}n_in_jn_kn_l/(4\\pi)`.

    Returns
    -------
    ndarray of float, shape (...), 1/steradian
        Integrates to 1 over the sphere for ranks 2 and 4 (0 for the
        difference). May be negative where a strongly anisotropic sample is
        poorly described by a low-rank truncation.

    Examples
    --------
    >>> t = fabric_tensors([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> round(float(fabric_density(t, [0, 0, 1], rank=2)) * 4 * np.pi, 12)
    1.0
    """
    d, shape = _unit_rows(directions)
    q2 = np.einsum("ni,nj,ij->n", d, d, tensors.D2)
    q4 = np.einsum("ni,nj,nk,nl,ijkl->n", d, d, d, d, tensors.D4, optimize=True)
    if rank == 2:
        f = 1.0 + q2
    elif rank == 4:
        f = 1.0 + q2 + q4
    elif rank == "difference":
        f = q4
    else:
        raise ValueError(f"`rank` must be 2, 4 or 'difference'; got {rank!r}")
    return (f / (4.0 * math.pi)).reshape(shape)


_PLANES = {"xy": (0, 1, 2), "xz": (0, 2, 1), "yz": (1, 2, 0)}


def projected_density(tensors: FabricTensors, angles, *, plane="xy", rank=4, n_quad=24):
    """Density of the in-plane angle of directions projected on a coordinate plane.

    For ``plane="xy"`` a direction :math:`n = (\\cos\\beta\\cos\\alpha,
    \\cos\\beta\\sin\\alpha, \\sin\\beta)` projects on the angle
    :math:`\\alpha`; the density of :math:`\\alpha` implied by the tensor
    approximation :math:`f` is

    .. math:: p(\\alpha) = \\int_{-\\pi/2}^{\\pi/2} f(n(\\alpha, \\beta)) \\cos\\beta \\, d\\beta ,

    integrated here by Gauss-Legendre quadrature (exact for these
    polynomials), so :math:`\\int_0^{2\\pi} p\\,d\\alpha = 1` (ranks 2 and 4).
    Planes ``"xz"`` and ``"yz"`` measure :math:`\\alpha` from the first
    named axis towards the second.

    Parameters
    ----------
    tensors : FabricTensors
    angles : array_like of float, radian
        In-plane angles :math:`\\alpha`.
    plane : {"xy", "xz", "yz"}
    rank : {2, 4, "difference"}
    n_quad : int
        Quadrature nodes in :math:`\\sin\\beta`.

    Returns
    -------
    ndarray of float, 1/radian, shape of ``angles``

    Examples
    --------
    >>> t = fabric_tensors([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> bool(np.allclose(projected_density(t, [0.0, 1.0], plane="xz", rank=2), 1 / (2 * np.pi)))
    True
    """
    if plane not in _PLANES:
        raise ValueError(f"`plane` must be one of {sorted(_PLANES)}; got {plane!r}")
    a = np.asarray(angles, dtype=np.float64)
    u, v, w = _PLANES[plane]
    s, ws = np.polynomial.legendre.leggauss(int(n_quad))   # s = sin(beta), ds = cos(beta) dbeta
    c = np.sqrt(1.0 - s * s)
    dirs = np.zeros(a.shape + s.shape + (3,))
    dirs[..., u] = np.cos(a)[..., None] * c
    dirs[..., v] = np.sin(a)[..., None] * c
    dirs[..., w] = s
    f = fabric_density(tensors, dirs, rank=rank)
    return np.einsum("...q,q->...", f, ws)


# --------------------------------------------------------------------------- sampling
def sample_directions(n: int, *, D2=None, D4=None, rng=None) -> np.ndarray:
    """Draw unit directions from :math:`f(n) = (1 + D_{ij}n_in_j + D_{ijkl}n_in_jn_kn_l)/(4\\pi)`.

    Rejection sampling from the uniform distribution on the sphere. Useful
    as a null model or to test estimators.

    Parameters
    ----------
    n : int
        Number of directions.
    D2 : (3, 3) array_like, optional
        Symmetric traceless rank-2 deviator (default 0).
    D4 : (3, 3, 3, 3) array_like, optional
        Fully symmetric traceless rank-4 deviator (default 0).
    rng : numpy.random.Generator or int, optional
        Random generator or seed.

    Returns
    -------
    (n, 3) ndarray of float
        Unit vectors.

    Raises
    ------
    ValueError
        If the density is negative somewhere (not a distribution).

    Examples
    --------
    >>> d = sample_directions(5, D2=np.diag([1.0, -0.5, -0.5]), rng=1)
    >>> d.shape, bool(np.allclose(np.linalg.norm(d, axis=1), 1))
    ((5, 3), True)
    """
    rng = np.random.default_rng(rng)
    d2 = np.zeros((3, 3)) if D2 is None else np.asarray(D2, dtype=np.float64)
    d4 = np.zeros((3, 3, 3, 3)) if D4 is None else np.asarray(D4, dtype=np.float64)
    if d2.shape != (3, 3) or d4.shape != (3, 3, 3, 3):
        raise ValueError(f"`D2` must have shape (3, 3) and `D4` (3, 3, 3, 3); got {d2.shape}, {d4.shape}")
    if abs(np.trace(d2)) > 1e-9 or np.abs(np.einsum("iikl->kl", d4)).max() > 1e-9:
        raise ValueError("`D2` and `D4` must be traceless (deviatoric)")

    def g(x):
        return (1.0 + np.einsum("ni,nj,ij->n", x, x, d2)
                + np.einsum("ni,nj,nk,nl,ijkl->n", x, x, x, x, d4, optimize=True))

    probe = rng.normal(size=(20000, 3))
    probe /= np.linalg.norm(probe, axis=1)[:, None]
    gp = g(probe)
    if gp.min() < 0:
        raise ValueError(f"the density is negative in some directions (min 4 pi f = {gp.min():.3g}); "
                         "D2/D4 do not describe a distribution")
    bound = 1.1 * gp.max() + 1e-12
    out = np.empty((0, 3))
    while out.shape[0] < n:
        k = max(1024, int(1.3 * (n - out.shape[0]) * bound))
        x = rng.normal(size=(k, 3))
        x /= np.linalg.norm(x, axis=1)[:, None]
        keep = rng.random(k) * bound < g(x)
        out = np.concatenate([out, x[keep]])
    return np.ascontiguousarray(out[:n])


# --------------------------------------------------------------------------- regions
def _axis_index(axis) -> int:
    if isinstance(axis, str):
        key = axis.lower()
        if key not in ("x", "y", "z"):
            raise ValueError(f"`axis` must be 0, 1, 2 or 'x', 'y', 'z'; got {axis!r}")
        return "xyz".index(key)
    if axis not in (0, 1, 2):
        raise ValueError(f"`axis` must be 0, 1, 2 or 'x', 'y', 'z'; got {axis!r}")
    return int(axis)


def contact_regions(contacts, frame, *, axis=0, n_regions: int = 3, position="midpoint",
                    bounds=None):
    """Split contacts into ``n_regions`` equal slabs along an axis by contact position.

    Parameters
    ----------
    contacts : Contacts
        Contacts of ``frame`` (``i``, ``j``, ``branch``, ``radii_i``, ``radii_j``).
    frame : Frame
        The frame the contacts index (for particle positions and the box).
    axis : {0, 1, 2, "x", "y", "z"}
        The spreading direction. Default x.
    n_regions : int
        Number of equal slabs (default 3: start, centre, end).
    position : {"midpoint", "particle"}
        ``"midpoint"``: the contact point on the branch vector weighted by
        radii, :math:`x_i + b\\, r_i/(r_i + r_j)` (the centre of the overlap
        lens for touching spheres), wrapped into the box on periodic axes;
        ``"particle"``: the centre of particle ``i``.
    bounds : (2,) array_like of float or "box", optional
        Extent (length) divided into slabs. Default: the range of the
        frame's particle centres along ``axis``; ``"box"``: the box
        ``lo``/``hi``. Contacts outside get region -1.

    Returns
    -------
    labels : (M,) ndarray of int
        Region of each contact, 0 (start) to ``n_regions - 1`` (end), or -1.
    edges : (n_regions + 1,) ndarray of float, length
        Slab boundaries.

    Examples
    --------
    >>> import bedstruct
    >>> f = bedstruct.Frame([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], [0.5] * 4,
    ...                     box=bedstruct.Box([-1, -1, -1], [4, 1, 1], boundary="ff ff ff"))
    >>> c = bedstruct.Contacts(i=[0, 1, 2], j=[1, 2, 3], branch=[[1, 0, 0]] * 3,
    ...                        radii_i=[0.5] * 3, radii_j=[0.5] * 3, n_particles=4)
    >>> labels, edges = contact_regions(c, f)
    >>> labels.tolist(), edges.tolist()
    ([0, 1, 2], [0.0, 1.0, 2.0, 3.0])
    """
    ax = _axis_index(axis)
    n_regions = int(n_regions)
    if n_regions < 1:
        raise ValueError(f"`n_regions` must be >= 1; got {n_regions}")
    if contacts.n_contacts and max(contacts.i.max(), contacts.j.max()) >= frame.n_particles:
        raise ValueError(f"`contacts` index particles up to {max(contacts.i.max(), contacts.j.max())} "
                         f"but `frame` has N={frame.n_particles}")
    if position == "midpoint":
        t = contacts.radii_i / (contacts.radii_i + contacts.radii_j)
        pts = frame.positions[contacts.i] + contacts.branch * t[:, None]
        if frame.box.periodic[ax] and pts.shape[0]:
            pts = frame.box.wrap(pts)
    elif position == "particle":
        pts = frame.positions[contacts.i]
    else:
        raise ValueError(f"`position` must be 'midpoint' or 'particle'; got {position!r}")
    if bounds is None:
        if frame.n_particles == 0:
            raise ValueError("`frame` has no particles; give `bounds`")
        lo, hi = float(frame.positions[:, ax].min()), float(frame.positions[:, ax].max())
    elif isinstance(bounds, str):
        if bounds != "box":
            raise ValueError(f"`bounds` must be (lo, hi) or 'box'; got {bounds!r}")
        lo, hi = float(frame.box.lo[ax]), float(frame.box.hi[ax])
    else:
        lo, hi = (float(b) for b in bounds)
    if not hi > lo:
        raise ValueError(f"`bounds` must satisfy lo < hi; got ({lo}, {hi})")
    edges = np.linspace(lo, hi, n_regions + 1)
    x = pts[:, ax]
    labels = np.floor((x - lo) / (hi - lo) * n_regions).astype(np.int64)
    labels[x == hi] = n_regions - 1
    labels[(x < lo) | (x > hi)] = -1
    return labels, edges


@dataclass(frozen=True)
class RegionFabric:
    """Fabric tensors of contacts in slabs along the spreading direction.

    Attributes
    ----------
    names : tuple of str
        ``("start", "centre", "end")`` for three regions, else ``"region k"``.
    edges : (n_regions + 1,) ndarray of float, length
        Slab boundaries along ``axis``.
    axis : int
        0, 1 or 2.
    tensors : tuple of FabricTensors or None
        One per region; None where a region has no contact.
    labels : (M,) ndarray of int
        Region of each contact (-1 outside).
    expansions : tuple of HarmonicExpansion or None, or None
        Per-region spherical-harmonic expansions when ``l_max`` was given.

    .. versionadded:: 0.1
    """

    names: tuple
    edges: np.ndarray
    axis: int
    tensors: tuple
    labels: np.ndarray = field(repr=False)
    expansions: tuple | None = field(default=None, repr=False)

    def __getitem__(self, key) -> FabricTensors | None:
        if isinstance(key, str):
            return self.tensors[self.names.index(key)]
        return self.tensors[key]

    def __len__(self) -> int:
        return len(self.tensors)


def region_fabric(contacts, frame, *, axis=0, n_regions: int = 3, weights=None,
                  position="midpoint", bounds=None, l_max: int | None = None) -> RegionFabric:
    """Fabric tensors of each slab (default thirds: start, centre, end) along an axis.

    Parameters
    ----------
    contacts, frame, axis, n_regions, position, bounds
        As for :func:`contact_regions`.
    weights : (M,) array_like or str, optional
        As for :func:`fabric_tensors` (strings select Contacts fields).
    l_max : int, optional
        Also expand each region in spherical harmonics to this degree
        (:func:`~bedstruct.analysis.harmonics.harmonic_expansion`).

    Returns
    -------
    RegionFabric

    Examples
    --------
    >>> import bedstruct
    >>> f = bedstruct.Frame([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], [0.5] * 4,
    ...                     box=bedstruct.Box([-1, -1, -1], [4, 1, 1], boundary="ff ff ff"))
    >>> c = bedstruct.Contacts(i=[0, 1, 2], j=[1, 2, 3], branch=[[1, 0, 0]] * 3,
    ...                        radii_i=[0.5] * 3, radii_j=[0.5] * 3, n_particles=4)
    >>> r = region_fabric(c, f)
    >>> r.names, float(r["start"].N2[0, 0])
    (('start', 'centre', 'end'), 1.0)
    """
    labels, edges = contact_regions(contacts, frame, axis=axis, n_regions=n_regions,
                                    position=position, bounds=bounds)
    m = contacts.n_contacts
    w = _resolve_weights(contacts, weights, m)
    normals = contacts.normals
    out = []
    exps = []
    if l_max is not None:
        from .harmonics import harmonic_expansion
    for k in range(int(n_regions)):
        sel = labels == k
        if not np.any(sel) or (w is not None and not w[sel].sum() > 0):
            out.append(None)
            exps.append(None)
            continue
        wk = None if w is None else w[sel]
        out.append(fabric_tensors(normals[sel], wk))
        if l_max is not None:
            exps.append(harmonic_expansion(normals[sel], l_max, wk))
    names = _REGION_NAMES_3 if n_regions == 3 else tuple(f"region {k}" for k in range(n_regions))
    labels.setflags(write=False)
    return RegionFabric(names=names, edges=_readonly(edges), axis=_axis_index(axis),
                        tensors=tuple(out), labels=labels,
                        expansions=None if l_max is None else tuple(exps))


# --------------------------------------------------------------------------- LAMMPS
def lammps_voigt(tensor) -> np.ndarray:
    """Components of a symmetric (3, 3) tensor in LAMMPS order ``xx yy zz xy xz yz``.

    Examples
    --------
    >>> lammps_voigt([[1, 4, 5], [4, 2, 6], [5, 6, 3]]).tolist()
    [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    """
    t = np.asarray(tensor, dtype=np.float64)
    if t.shape != (3, 3):
        raise ValueError(f"`tensor` must have shape (3, 3); got {t.shape}")
    return np.array([t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]])


@dataclass(frozen=True)
class LammpsFabric:
    """The vector of LAMMPS ``compute fabric`` for one set of contacts.

    Each field is a (6,) array in LAMMPS order ``xx yy zz xy xz yz``, or
    None when the input needed for it was not given.

    Attributes
    ----------
    contact : (6,) ndarray
        Contact tensor; equals :func:`lammps_voigt` of :attr:`FabricTensors.D2`.
    branch : (6,) ndarray or None
        Branch tensor (needs branch lengths).
    force_normal : (6,) ndarray or None
        Normal-force tensor (needs normal-force magnitudes).
    force_tangential : (6,) ndarray or None
        Tangential-force tensor (needs normal and tangential magnitudes).
    n_contacts : int
        The scalar output (number of pairs).
    """

    contact: np.ndarray
    branch: np.ndarray | None
    force_normal: np.ndarray | None
    force_tangential: np.ndarray | None
    n_contacts: int


def lammps_fabric(normals, *, branch_lengths=None, force_normal=None,
                  force_tangential=None) -> LammpsFabric:
    """Fabric tensors with the conventions of LAMMPS ``compute fabric`` (GRANULAR package).

    Follows the LAMMPS source (``compute_fabric.cpp``): with
    :math:`\\phi_{ab} = N_c^{-1}\\sum n_a n_b` (our ``N2``),
    the contact tensor is :math:`A_{ab} = \\tfrac{15}{2}(\\phi_{ab} - \\tfrac13
    \\phi_{cc}\\delta_{ab})`, which is exactly our third-kind ``D2``. The
    branch and force tensors weight each pair by
    :math:`1 / (N_c (1 + A_{cd} n_c n_d))` (the contact density) times the
    branch length ``l``, ``f_n`` or ``f_t``, giving :math:`X_{ab}`, and
    report :math:`\\tfrac{15}{2\\,\\mathrm{tr}X}(X_{ab} - \\tfrac13 \\mathrm{tr}X
    \\,\\delta_{ab})`; the tangential tensor uses
    :math:`\\tfrac{15}{3\\,\\mathrm{tr}X^{n}}(X^t_{ab} - \\tfrac13 \\mathrm{tr}X^t\\delta_{ab})`
    (Ouadfel & Rothenburg 2001). The LAMMPS manual prints
    :math:`\\mathrm{Tr}(\\phi)` where the code subtracts one third of the
    trace and normalises by :math:`N_c`; we follow the code.

    Parameters
    ----------
    normals : (M, 3) array_like of float, or Contacts
        Pair directions (sign irrelevant). With a Contacts object the
        branch lengths and force magnitudes default to its fields.
    branch_lengths, force_normal, force_tangential : (M,) array_like of float, optional
        Branch lengths (length) and force magnitudes (force).

    Returns
    -------
    LammpsFabric

    Examples
    --------
    >>> lf = lammps_fabric([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0]])
    >>> lf.contact.round(6).tolist()
    [1.25, -0.625, -0.625, 0.0, 0.0, 0.0]
    """
    src = normals
    n = _as_directions(normals)
    norm = np.sqrt(np.einsum("ij,ij->i", n, n))
    if np.any(norm == 0):
        raise ValueError("`normals` contains zero vectors; LAMMPS never counts such pairs")
    n = n / norm[:, None]
    m = n.shape[0]
    if m == 0:
        z = np.zeros(6)
        return LammpsFabric(z, None, None, None, 0)
    if hasattr(src, "branch") and hasattr(src, "normals"):
        if branch_lengths is None:
            branch_lengths = src.distance
        if force_normal is None and src.force_normal is not None:
            force_normal = np.sqrt(np.einsum("ij,ij->i", src.force_normal, src.force_normal))
        if force_tangential is None and src.force_tangential is not None:
            force_tangential = np.sqrt(np.einsum("ij,ij->i", src.force_tangential,
                                                 src.force_tangential))
    phi = np.einsum("ni,nj->ij", n, n) / m
    a = 7.5 * (phi - np.trace(phi) / 3.0 * _DELTA)
    pref = 1.0 / (m * (1.0 + np.einsum("ni,nj,ij->n", n, n, a)))

    def tensor(values, name):
        v = _resolve_weights(None, values, m)
        x = np.einsum("n,ni,nj->ij", pref * v, n, n)
        return x, float(np.trace(x)) / 3.0

    def deviator(x, tr3, scale):
        return lammps_voigt(scale * (x - tr3 * _DELTA))

    br = fn = ft = None
    if branch_lengths is not None:
        x, tr3 = tensor(branch_lengths, "branch_lengths")
        br = deviator(x, tr3, 15.0 / (6.0 * tr3))
    if force_normal is not None:
        xn, trn3 = tensor(force_normal, "force_normal")
        fn = deviator(xn, trn3, 15.0 / (6.0 * trn3))
        if force_tangential is not None:
            xt, trt3 = tensor(force_tangential, "force_tangential")
            ft = deviator(xt, trt3, 15.0 / (9.0 * trn3))
    elif force_tangential is not None:
        raise ValueError("`force_tangential` needs `force_normal` (LAMMPS normalises by it)")
    return LammpsFabric(contact=lammps_voigt(a), branch=br, force_normal=fn,
                        force_tangential=ft, n_contacts=m)


# --------------------------------------------------------------------------- table
_COMP = ("xx", "yy", "zz", "xy", "xz", "yz")


def fabric_table(results: Sequence[FabricTensors | None], *, labels=None) -> dict:
    """Columns (dict of equal-length arrays) summarising several FabricTensors, for pandas.

    Parameters
    ----------
    results : sequence of FabricTensors or None
        E.g. ``region_fabric(...).tensors`` or one per frame. None rows
        (empty regions) become NaN.
    labels : sequence, optional
        A label per row (``label`` column); default the row index.

    Returns
    -------
    dict of str to (K,) ndarray
        ``label``, ``n_contacts``, ``total_weight``, ``N2_xx`` ... ``N2_yz``,
        ``D2_xx`` ... ``D2_yz``, ``lambda1..3`` (eigenvalues of N2,
        descending), ``anisotropy`` and ``anisotropy_rank4``. Zero-length
        typed columns for empty input.

    Examples
    --------
    >>> t = fabric_tensors([[1, 0, 0], [0, 1, 0]])
    >>> tab = fabric_table([t, None], labels=["a", "b"])
    >>> tab["N2_xx"].tolist(), tab["n_contacts"].tolist()
    ([0.5, nan], [2, 0])
    """
    results = list(results)
    k = len(results)
    labels = np.arange(k) if labels is None else np.asarray(list(labels))
    if labels.shape != (k,):
        raise ValueError(f"`labels` must have one entry per result ({k}); got {labels.shape}")
    tab = {"label": labels,
           "n_contacts": np.array([0 if r is None else r.n_contacts for r in results], dtype=np.int64),
           "total_weight": np.array([np.nan if r is None else r.total_weight for r in results],
                                    dtype=np.float64)}
    for name in ("N2", "D2"):
        vals = np.array([np.full(6, np.nan) if r is None else lammps_voigt(getattr(r, name))
                         for r in results], dtype=np.float64).reshape(k, 6)
        for c, comp in enumerate(_COMP):
            tab[f"{name}_{comp}"] = vals[:, c]
    eig = np.array([np.full(3, np.nan) if r is None else r.eigenvalues for r in results],
                   dtype=np.float64).reshape(k, 3)
    for c in range(3):
        tab[f"lambda{c + 1}"] = eig[:, c]
    for name in ("anisotropy", "anisotropy_rank4"):
        tab[name] = np.array([np.nan if r is None else getattr(r, name) for r in results],
                             dtype=np.float64)
    return tab
